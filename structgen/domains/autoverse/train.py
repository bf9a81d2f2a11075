"""``structgen autoverse train``: a player for an evolution run's games, cloned from the search's playtraces, then
trained by PPO, optionally on games that evolve to stay hard for it (the paper's open-ended phase).

1. **Cloning** (``clone_steps`` > 0): the run's playtraces split as :func:`.clone.split` splits them, the policy
   fitted to the training games' traces (:func:`.clone.fit_policy`).
2. **PPO** from the cloned weights (:mod:`structgen.ppo`): ``envs`` games played at once, each episode on a game
   drawn at random from the training pool when the last one ends; rewards are the original's normalised rewards of
   the game being played (:func:`.clone.normalisation`).
3. **Regret-driven evolution** (``evolve_every`` > 0): every that many updates each game of the pool has one
   mutated child; parents and children are played for one episode by the current policy and scored by the sum over
   the episode of |G_t - V(s_t)| (the discounted return still to come against the value the agent predicted, the
   original's proxy for regret: where the agent mispredicts, it still has something to learn); the pool keeps the
   ``pool`` highest. The pool starts as the training games.

Every ``evaluate_every`` updates (and after cloning, as update 0) the policy plays each training, validation and test
game for ``eval_steps`` steps; the learning curve shows the mean normalised return per episode of each split.

The run folder holds ``config.toml``, ``manifest.json``, ``cloned.pt`` (the policy after cloning, so that a resumed
run does not clone again), ``checkpoint.pt`` (weights, optimiser, the games in play and in the pool, random states),
``history.jsonl``, ``learning.png``, with evolution ``evolution.png``, and at the end ``policy.pt``. The same command
on the same folder resumes it; more ``updates`` go on.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch

from evolution import RunFolder
from structgen.domains.autoverse.clone import (
    EvaluationGames,
    Policy,
    collect_playtraces,
    evaluate_policy,
    fit_policy,
    normalisation,
    split,
    transitions,
)
from structgen.domains.autoverse.engine import EPISODE_STEPS, FLAT_SIZE, VIEW, Engine, Mechanics, Observation, stack_games
from structgen.domains.autoverse.game import check_game, mutate_game
from structgen.domains.autoverse.ppo import GamePool
from structgen.domains.autoverse.train_settings import TrainSettings
from structgen.errors import InputError
from structgen.ppo import PPO, EpisodeReturns, check_rollout_memory
from structgen.runs.training_folder import (
    checked_like,
    checked_optimiser,
    checked_weights,
    checked_whole,
    load_torch,
    new_folder_removed_on_failure,
    open_training_folder,
    read_history,
    read_training_settings,
    save_torch,
    write_history,
    write_training_settings,
)

__all__ = ["RUN_KIND", "TrainSettings", "evolve_pool", "regret_scores", "train"]

RUN_KIND = "autoverse-player"
DOMAIN = "autoverse-v0"
CHECKPOINT_FILE, CLONED_FILE, POLICY_FILE = "checkpoint.pt", "cloned.pt", "policy.pt"
LEARNING_PLOT, EVOLUTION_PLOT = "learning.png", "evolution.png"
_TABLE, _HEADER = "train", "Settings of this Autoverse player's training (structgen autoverse train)"


@torch.no_grad()
def regret_scores(policy: Policy, games: list[dict[str, Any]], observation: Observation, gamma: float, seed: int) -> np.ndarray:
    """Per game: the sum over one episode (actions sampled from ``policy``) of |G_t - V(s_t)|, with G_t the
    discounted normalised return from step t to the episode's end."""
    engine = Engine(games, device=next(policy.parameters()).device, mechanics=Mechanics())
    bias, scale = normalisation(engine)
    generator = torch.Generator(device=engine.device).manual_seed(seed)
    state = engine.reset()
    values, rewards = [], []
    for _ in range(EPISODE_STEPS + 1):
        logits, value = policy(*engine.observe(state, observation))
        action = torch.multinomial(torch.softmax(logits, dim=1), 1, generator=generator).squeeze(1)
        state, reward, _ = engine.step(state, action)
        values.append(value)
        rewards.append((reward + bias / EPISODE_STEPS) * scale)
    to_come = torch.zeros(len(games), device=engine.device)
    error = torch.zeros(len(games), device=engine.device)
    for value, reward in zip(reversed(values), reversed(rewards)):
        to_come = reward + gamma * to_come
        error += (to_come - value).abs()
    return error.cpu().numpy()


def evolve_pool(
    policy: Policy, pool: list[dict[str, Any]], settings: TrainSettings, size: int, rng: np.random.Generator, seed: int
) -> tuple[list[dict[str, Any]], np.ndarray]:
    """One round: a mutated child per game, parents and children scored by :func:`regret_scores`, the ``size``
    highest kept (ties by order). Returns the new pool and its scores."""
    children = [mutate_game(game, rng, settings.evolve_mutation) for game in pool]
    together = pool + children
    scores = regret_scores(policy, together, settings.observation(), settings.gamma, seed)
    keep = np.argsort(-scores, kind="stable")[:size]
    return [together[i] for i in keep], scores[keep]


def evaluation_games(games: list[dict[str, Any]], count: int) -> list[dict[str, Any]]:
    """``count`` games evenly spaced along ``games`` (a split, in order of fitness); all of them for 0."""
    if count == 0 or count >= len(games):
        return games
    return [games[i] for i in np.unique(np.linspace(0, len(games) - 1, count).round().astype(int))]


def _evaluation_splits(parts: dict[str, list[dict[str, Any]]], settings: TrainSettings) -> dict[str, EvaluationGames]:
    """Each split's evaluation games, made ready once for every evaluation of the training."""
    chosen = {name: evaluation_games(games, settings.eval_games) for name, games in parts.items()}
    return {name: EvaluationGames(games, settings.seed, settings.device) for name, games in chosen.items() if games}


def _evaluate(policy: Policy, splits: dict[str, EvaluationGames], settings: TrainSettings) -> dict[str, float]:
    """Mean normalised return per episode (over ``eval_steps`` steps of each game) of each split."""
    episodes = settings.eval_steps / (EPISODE_STEPS + 1)
    was_training = policy.training
    policy.eval()
    observation = settings.observation()
    scores = {
        name: float(np.mean(evaluate_policy(policy, games, observation, settings.eval_steps, settings.seed))) / episodes
        for name, games in splits.items()
    }
    policy.train(was_training)
    return scores


def learning_figure(rows: list[dict[str, Any]]) -> Any:
    from evolution.plots import new_figure

    figure = new_figure(figsize=(7, 4))
    axes = figure.add_subplot(1, 1, 1)
    tested = [row for row in rows if "test" in row]
    for name, label in (("train", "training games"), ("val", "validation games"), ("test", "test games (held out)")):
        marked = [row for row in tested if name in row]
        axes.plot([r["update"] for r in marked], [r[name] for r in marked], "o-", label=label)
    played = [row for row in rows if row.get("return") is not None]
    if played:
        axes.plot([r["update"] for r in played], [r["return"] for r in played], alpha=0.4, label="episodes played in training")
    axes.set_xlabel("PPO update (0: after cloning)")
    axes.set_ylabel("normalised return per episode")
    axes.grid(alpha=0.3)
    axes.legend(loc="best")
    axes.set_title("Autoverse player: behaviour cloning, then PPO")
    return figure


def evolution_figure(rows: list[dict[str, Any]]) -> Any:
    from evolution.plots import new_figure

    figure = new_figure(figsize=(7, 6))
    top, bottom = figure.add_subplot(2, 1, 1), figure.add_subplot(2, 1, 2, sharex=None)
    top.set_xlabel("PPO update")
    evolved = [row for row in rows if "pool_regret" in row]
    top.plot([r["update"] for r in evolved], [r["pool_regret"] for r in evolved], "o-", label="mean over the pool")
    top.plot([r["update"] for r in evolved], [r["pool_regret_max"] for r in evolved], "s--", label="highest")
    top.set_ylabel("sum of |G - V| per episode")
    top.set_yscale("symlog")  # one cascading game can score a million times the rest
    top.set_title("games evolved for the agent's value error")
    top.legend(loc="best")
    top.grid(alpha=0.3)
    tested = [row for row in rows if "test" in row]
    bottom.plot([r["update"] for r in tested], [r["test"] for r in tested], "o-", color="C2", label="test games (held out)")
    bottom.set_xlabel("PPO update")
    bottom.set_ylabel("normalised return per episode")
    bottom.legend(loc="best")
    bottom.grid(alpha=0.3)
    return figure


def _pictures(rows: list[dict[str, Any]], settings: TrainSettings) -> dict[str, Any]:
    pictures = {LEARNING_PLOT: learning_figure(rows)}
    if settings.evolve_every:
        pictures[EVOLUTION_PLOT] = evolution_figure(rows)
    return pictures


def _checked_policy(path: Path, policy: Policy) -> dict[str, Any]:
    """``cloned.pt``'s weights, checked against the network they are for."""
    saved = load_torch(path, "a player's cloned weights")
    weights = checked_weights(saved, "policy", path)
    checked_like(policy.state_dict(), weights, path, "policy")
    return weights


def _checked_checkpoint(
    path: Path, settings: TrainSettings, policy: Policy, env: GamePool, pool: list[dict[str, Any]]
) -> dict[str, Any]:
    """The training checkpoint at ``path`` with every part checked against what this training holds before any of
    it is restored (a damaged, foreign or tampered checkpoint is refused naming the field, and nothing changes)."""
    saved = load_torch(path, "an Autoverse player's training checkpoint")
    if not isinstance(saved, dict):
        raise InputError(f"{path}: not an Autoverse player's training checkpoint (a {type(saved).__name__})")
    checked_whole(saved, "update", path, 0, settings.updates)
    checked_like(policy.state_dict(), checked_weights(saved, "policy", path), path, "policy")
    checked_optimiser(saved, "optimiser", path, list(policy.parameters()))
    # The pool's size changes as it evolves: one game gives each array's type and number of dimensions.
    reference = _pool_arrays(pool[:1])
    games = checked_like(reference, saved.get("pool"), path, "pool", varying=tuple(reference))
    count = len(games["rewards"])
    if count == 0 or any(len(value) != count for value in games.values()):
        raise InputError(f"{path}: pool holds {count} games (its arrays must be non-empty and of one length)")
    if games["map"].shape[1:] != reference["map"].shape[1:]:
        raise InputError(f"{path}: pool maps have shape {tuple(games['map'].shape[1:])}; this training's games "
                         f"{tuple(reference['map'].shape[1:])}")  # fmt: skip
    for number, game in enumerate(_pool_from(games)):  # each game as a game file's would be: tiles, rules, one player
        check_game(game, f"{path}: pool game {number}")
    state = checked_like(env.state_dict(), saved.get("env"), path, "env")
    if int(state["game"].min()) < 0 or int(state["game"].max()) >= count:
        raise InputError(f"{path}: env.game names games the pool does not hold")
    checked_like(torch.Generator().get_state(), saved.get("generator"), path, "generator")
    checked_like(torch.get_rng_state(), saved.get("torch_rng"), path, "torch_rng")
    checked_like(EpisodeReturns(settings.envs, "cpu").running, saved.get("running"), path, "running")
    if not isinstance(saved.get("rng"), str):
        raise InputError(f"{path}: field 'rng' is {type(saved.get('rng')).__name__}; expected the generator's state as JSON")
    return saved


def _pool_arrays(pool: list[dict[str, Any]]) -> dict[str, torch.Tensor]:
    return {key: torch.as_tensor(value) for key, value in stack_games(pool).items()}


def _pool_from(arrays: dict[str, torch.Tensor]) -> list[dict[str, Any]]:
    count = len(arrays["rewards"])
    return [{key: arrays[key][i].numpy() for key in ("rules", "rewards", "map")} for i in range(count)]


def read_settings(folder: RunFolder) -> TrainSettings:
    return read_training_settings(folder, TrainSettings, _TABLE)


def source_run(output: str | Path) -> Path:
    """The evolution run whose games the training in ``output`` learns from."""
    source = RunFolder(output).manifest().get("source_run")
    if not isinstance(source, str) or not source or "\0" in source:
        raise InputError(
            f"{Path(output) / RunFolder.MANIFEST}: field 'source_run' is {source!r}; expected the path of the run this "
            "training learns from"
        )
    return Path(source)


def training_summary(output: str | Path) -> dict[str, Any]:
    """What ``structgen info`` says of a training folder: settings, progress, the last evaluation."""
    folder = RunFolder(output)
    settings = read_settings(folder)
    rows = read_history(folder, settings.updates)
    tested = [row for row in rows if "test" in row]
    return {
        "run_dir": str(output),
        "run_kind": RUN_KIND,
        "source_run": str(source_run(output)),
        "updates": settings.updates,
        "updates_done": rows[-1]["update"] if rows else 0,
        "test": tested[-1]["test"] if tested else None,
        "finished": (folder / POLICY_FILE).is_file(),
        "settings": asdict(settings),
    }


def train(
    run_dir: str | Path, output: str | Path, settings: TrainSettings, *, overwrite: bool = False, progress: bool = True
) -> list[dict[str, Any]]:
    """Train (or resume training) a player for the games of the Autoverse run ``run_dir`` in the folder ``output``;
    returns the history rows."""

    from structgen.devices import resolve_device

    resolve_device(settings.device, "train device")
    parts = split(collect_playtraces(Path(run_dir), settings.min_fitness))
    if not parts["train"]:
        raise InputError(f"{run_dir}: no game with fitness >= {settings.min_fitness} to learn from")
    one = GamePool(list(parts["train"][:1]), 1, settings.observation(), "cpu", torch.Generator().manual_seed(0))
    check_rollout_memory(one.observe(), settings.envs, settings.steps, what="--envs and --steps")
    with new_folder_removed_on_failure(Path(output), CHECKPOINT_FILE, CLONED_FILE):
        return _train(run_dir, output, settings, parts, overwrite, progress)


def _train(
    run_dir: str | Path, output: str | Path, settings: TrainSettings, parts: dict[str, Any], overwrite: bool, progress: bool
) -> list[dict[str, Any]]:
    from tqdm import tqdm

    folder = open_training_folder(
        Path(output),
        settings,
        run_kind=RUN_KIND,
        domain=DOMAIN,
        table=_TABLE,
        header=_HEADER,
        overwrite=overwrite,
        about={"source_run": str(Path(run_dir).resolve())},
        reads=(run_dir,),
    )
    torch.manual_seed(settings.seed)
    observation = settings.observation()
    splits = _evaluation_splits(parts, settings)
    policy = Policy(FLAT_SIZE, settings.hidden, VIEW).to(settings.device)
    with folder.locked():
        checkpoint = folder / CHECKPOINT_FILE
        cloned = folder / CLONED_FILE
        # Everything read back is checked before anything is trained or written; a path that is there but is not a
        # regular file (a link to a device, a FIFO) is refused, not taken for "no checkpoint yet".
        saved = None
        if checkpoint.exists() or checkpoint.is_symlink():
            pool_now = list(parts["train"])
            probe = GamePool(pool_now, settings.envs, observation, "cpu", torch.Generator().manual_seed(0))
            saved = _checked_checkpoint(checkpoint, settings, policy, probe, pool_now)
        first_rows = read_history(folder, int(saved["update"]) if saved is not None else 0)
        if cloned.exists() or cloned.is_symlink():
            policy.load_state_dict(_checked_policy(cloned, policy))
        elif saved is not None:
            raise InputError(f"{cloned}: missing while {checkpoint} is there; this folder was tampered with")
        write_training_settings(folder, settings, _TABLE, _HEADER)
        if not (cloned.exists() or cloned.is_symlink()):
            if settings.clone_steps:
                views, flats, actions = transitions(parts["train"], observation, device=settings.device)
                fit_policy(
                    policy, views, flats, actions, settings.clone_steps, settings.clone_batch,
                    settings.clone_learning_rate, settings.seed, progress,
                )  # fmt: skip
                del views, flats, actions
            first = {"update": 0, "agent_steps": 0, **_evaluate(policy, splits, settings)}
            save_torch(folder / CLONED_FILE, {"policy": policy.state_dict(), "evaluation": first})
            write_history(folder, [first], _pictures([first], settings))
        ppo = PPO(policy, settings)
        generator = torch.Generator().manual_seed(settings.seed)
        rng = np.random.default_rng([settings.seed, 2])
        pool = list(parts["train"])
        size = settings.pool or len(pool)
        done = 0
        returns = EpisodeReturns(settings.envs, settings.device)
        if saved is not None:
            pool = _pool_from(saved["pool"])
        env = GamePool(pool, settings.envs, observation, settings.device, generator)
        if saved is not None:
            try:
                ppo.policy.load_state_dict(saved["policy"])
                ppo.optimiser.load_state_dict(saved["optimiser"])
                env.load_state_dict(saved["env"])
                generator.set_state(saved["generator"])
                rng.bit_generator.state = json.loads(saved["rng"])
                torch.set_rng_state(saved["torch_rng"])
                returns.running = saved["running"].to(returns.running.device)
            except (KeyError, RuntimeError, ValueError, TypeError) as err:
                raise InputError(f"{checkpoint}: cannot resume from this checkpoint ({type(err).__name__}: {err})") from None
            done = int(saved["update"])
        rows = first_rows if saved is not None else read_history(folder, done)
        bar = tqdm(total=settings.updates, initial=done, desc="autoverse PPO", unit="update", disable=not progress)
        while done < settings.updates:
            started = time.perf_counter()
            rollout = ppo.collect(env, env.observe())
            ended = returns.add_rollout(rollout)
            losses = ppo.update(rollout)
            done += 1
            row: dict[str, Any] = {
                "update": done,
                "agent_steps": done * settings.envs * settings.steps,
                "episodes": len(ended),
                "return": float(np.mean(ended)) if ended else None,
                **losses,
            }
            if settings.evolve_every and done % settings.evolve_every == 0:
                pool, scores = evolve_pool(ppo.policy, pool, settings, size, rng, settings.seed + done)
                env = GamePool(pool, settings.envs, observation, settings.device, generator)
                returns = EpisodeReturns(settings.envs, settings.device)  # the episodes in play were cut off
                row.update(pool_regret=float(scores.mean()), pool_regret_max=float(scores.max()))
            if done % settings.evaluate_every == 0 or done == settings.updates:
                row.update(_evaluate(ppo.policy, splits, settings))
            row["seconds"] = time.perf_counter() - started
            rows.append(row)
            bar.update(1)
            bar.set_postfix({k: round(row[k], 2) for k in ("return", "test") if row.get(k) is not None})
            if done % settings.checkpoint_every == 0 or done == settings.updates:
                save_torch(
                    checkpoint,
                    {
                        "update": done,
                        "policy": ppo.policy.state_dict(),
                        "optimiser": ppo.optimiser.state_dict(),
                        "env": env.state_dict(),
                        "pool": _pool_arrays(pool),
                        "generator": generator.get_state(),
                        "rng": json.dumps(rng.bit_generator.state),
                        "running": returns.running,
                        "torch_rng": torch.get_rng_state(),
                    },
                )
                write_history(folder, rows, _pictures(rows, settings))
        bar.close()
        save_torch(folder / POLICY_FILE, {"policy": ppo.policy.state_dict(), "settings": asdict(settings), "updates": done})
    return rows
