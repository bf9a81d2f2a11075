"""Training the maze agent (:mod:`.agent`): PPO (:mod:`structgen.ppo`) with a curriculum of levels in the
spirit of PLR and ACCEL, in a run folder that checkpoints and resumes.

The curriculum keeps a buffer of levels scored by their learning potential: the mean positive advantage of the
agent's last steps on them (PLR's "positive value loss": where the agent did better than it expected, it still
has something to learn). When an episode ends, its environment gets the next level: with probability ``replay`` a
level from the buffer, drawn by the rank of its score (temperature ``temperature``) mixed with how long ago it was
played (``staleness``); otherwise a new level, which is with probability ``edit`` a high-scoring buffer level with
1-4 cells flipped (ACCEL's edits) and else a fresh random maze (scattered walls or carved corridors, half each). The
buffer keeps the ``buffer`` best-scoring levels.

A run folder holds ``config.toml`` (the settings), ``manifest.json``, ``checkpoint.pt`` (everything needed to go on
exactly where it stood: weights, optimiser, levels in play and in the buffer, random states), ``history.jsonl``
(one row per update), ``learning.png`` and, at the end, ``agent.pt`` (the weights, as :func:`load_agent` reads
them). The same command on the same folder resumes it.
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
from evolution.files import MiB
from structgen.domains.layouts.maze.agent import MazePolicy, RememberingMazes, run_agent
from structgen.domains.layouts.maze.agent_settings import AgentSettings
from structgen.domains.layouts.maze.env import TorchMazes, _has_two_connected_floor_cells, random_maze
from structgen.errors import InputError
from structgen.ppo import PPO, check_rollout_memory
from structgen.runs.training_folder import (
    checked_like,
    checked_optimiser,
    checked_weights,
    checked_whole,
    is_training_folder,
    load_torch,
    new_folder_removed_on_failure,
    one_line,
    open_training_folder,
    read_history,
    read_training_settings,
    save_torch,
    write_history,
    write_training_settings,
)

__all__ = ["AgentSettings", "Curriculum", "RUN_KIND", "agent_policy", "load_agent", "save_agent", "train_agent"]

RUN_KIND = "maze-agent"
DOMAIN = "maze-v0"
CHECKPOINT_FILE, AGENT_FILE, PLOT_FILE = "checkpoint.pt", "agent.pt", "learning.png"
#: The kinds of random maze the agent trains on; ``rooms`` is kept for testing it on something new.
TRAINING_KINDS = ("scattered", "carved")
#: Held-out mazes of the learning curve: ``rooms`` mazes from this seed.
HELD_OUT_SEED, HELD_OUT_COUNT = 12345, 100
_MAX_AGENT_BYTES = 64 * MiB
#: The widest network an agent file may ask for (the command line's --hidden allows as much).
MAX_HIDDEN = 4096


class Curriculum:
    """The level buffer and the choice of next levels (see the module). Levels in play and in the buffer are kept
    by id in :attr:`levels`."""

    def __init__(self, settings: AgentSettings) -> None:
        self.settings = settings
        self.rng = np.random.default_rng([settings.seed, 1])
        self.levels: dict[int, np.ndarray] = {}
        self.scores: dict[int, float] = {}  # the buffer: level id -> score
        self.played: dict[int, int] = {}  # level id -> the update it was last played in
        self.next_id = 0
        self.update = 0

    def _add(self, maze: np.ndarray) -> int:
        self.levels[self.next_id] = maze
        self.next_id += 1
        return self.next_id - 1

    def fresh(self) -> int:
        kind = TRAINING_KINDS[int(self.rng.integers(len(TRAINING_KINDS)))]
        return self._add(random_maze(self.rng, self.settings.size, kind))

    def _draw(self, ids: list[int], by_score: np.ndarray, staleness: float) -> int:
        ranks = np.empty(len(ids))
        ranks[np.argsort(-by_score, kind="stable")] = np.arange(1, len(ids) + 1)
        weights = (1.0 / ranks) ** (1.0 / self.settings.temperature)
        chance = weights / weights.sum()
        if staleness > 0:
            age = self.update - np.array([self.played.get(i, 0) for i in ids], dtype=float)
            stale = age / age.sum() if age.sum() > 0 else np.full(len(ids), 1.0 / len(ids))
            chance = (1 - staleness) * chance + staleness * stale
        return ids[int(self.rng.choice(len(ids), p=chance))]

    def _edited(self, parent: np.ndarray) -> np.ndarray:
        while True:
            child = parent.copy()
            flips = self.rng.integers(0, child.size, int(self.rng.integers(1, 5)))
            child.flat[flips] ^= 1
            if _has_two_connected_floor_cells(child):
                return child

    def next_level(self) -> int:
        """The id of the level an environment plays next."""
        s = self.settings
        ids = list(self.scores)
        if len(ids) >= min(s.buffer, 64):
            scores = np.array([self.scores[i] for i in ids])
            if self.rng.random() < s.replay:
                return self._draw(ids, scores, s.staleness)
            if self.rng.random() < s.edit:
                return self._add(self._edited(self.levels[self._draw(ids, scores, 0.0)]))
        return self.fresh()

    def score(self, level_ids: torch.Tensor, advantages: torch.Tensor, in_play: set[int]) -> None:
        """Score every level played in a rollout (``level_ids`` and ``advantages``: ``(steps, envs)``) by its mean
        positive advantage, keep the best ``buffer`` and forget levels neither kept nor in play."""
        self.update += 1
        ids = level_ids.reshape(-1).cpu().numpy()
        gain = advantages.clamp(min=0).reshape(-1).cpu().numpy()
        unique, inverse = np.unique(ids, return_inverse=True)
        means = np.bincount(inverse, weights=gain) / np.bincount(inverse)
        for level, mean in zip(unique.tolist(), means.tolist()):
            self.scores[level] = mean
            self.played[level] = self.update
        if len(self.scores) > self.settings.buffer:
            ordered = sorted(self.scores, key=lambda i: (self.scores[i], i))
            for level in ordered[: len(self.scores) - self.settings.buffer]:
                del self.scores[level]
        for level in [i for i in self.levels if i not in self.scores and i not in in_play]:
            del self.levels[level]
            self.played.pop(level, None)

    def state_dict(self) -> dict[str, Any]:
        ids = sorted(self.levels)
        return {
            "ids": torch.as_tensor(ids, dtype=torch.int64),
            "levels": torch.as_tensor(np.stack([self.levels[i] for i in ids])),
            "scores": json.dumps({str(k): v for k, v in self.scores.items()}),
            "played": json.dumps({str(k): v for k, v in self.played.items()}),
            "next_id": self.next_id,
            "update": self.update,
            "rng": json.dumps(self.rng.bit_generator.state),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.levels = {int(i): level.numpy() for i, level in zip(state["ids"], state["levels"])}
        self.scores = {int(k): float(v) for k, v in json.loads(state["scores"]).items()}
        self.played = {int(k): int(v) for k, v in json.loads(state["played"]).items()}
        self.next_id, self.update = int(state["next_id"]), int(state["update"])
        self.rng.bit_generator.state = json.loads(state["rng"])


class CurriculumMazes:
    """:class:`.agent.RememberingMazes` whose environments take their next level from a :class:`Curriculum`
    when an episode ends. :attr:`log` holds the level id of every step since it was last emptied; :attr:`ended`
    the ``(reached, return)`` of every episode that ended."""

    def __init__(self, curriculum: Curriculum, settings: AgentSettings) -> None:
        self.curriculum = curriculum
        self.in_play = [curriculum.fresh() for _ in range(settings.envs)]
        mazes = TorchMazes([curriculum.levels[i] for i in self.in_play], device=settings.device, seed=settings.seed)
        self.env = RememberingMazes(mazes, way_on=settings.way_on)
        self.log: list[torch.Tensor] = []
        self.ended: list[tuple[bool, float]] = []

    def step(self, actions: torch.Tensor) -> tuple[tuple[torch.Tensor, torch.Tensor], torch.Tensor, torch.Tensor]:
        self.log.append(torch.as_tensor(self.in_play))
        observation, reward, done = self.env.step(actions)
        if bool(done.any()):
            rows = done.nonzero().flatten()
            reached, gained = self.env.reached[rows].tolist(), reward[rows].tolist()
            self.ended.extend(zip(reached, gained))
            for row in rows.tolist():
                self.in_play[row] = self.curriculum.next_level()
            self.env.mazes.set_levels([self.curriculum.levels[self.in_play[r]] for r in rows.tolist()], rows)
            observation = self.env.restart(rows)
        return observation, reward, done


def held_out_mazes(size: int) -> list[np.ndarray]:
    """The learning curve's test: ``rooms`` mazes, a kind the agent never trains on."""
    rng = np.random.default_rng(HELD_OUT_SEED)
    return [random_maze(rng, size, "rooms") for _ in range(HELD_OUT_COUNT)]


# --- weights ------------------------------------------------------------------------------------------------------------------
def save_agent(path: str | Path, policy: MazePolicy, **about: Any) -> Path:
    """Write the agent's weights with what made them (``about``: plain values) to ``path``, atomically."""
    saved = {"format": "structgen maze agent 1", "hidden": policy.hidden, "way_on": policy.way_on, "policy": policy.state_dict()}
    return save_torch(path, {**saved, **about})


def load_agent(path: str | Path) -> tuple[MazePolicy, dict[str, Any]]:
    """The agent :func:`save_agent` wrote (a run folder's ``agent.pt``, or the shipped ``docs/maze_agent.pt``) and
    what it records about its training; a file that is not one is refused naming it and the field at fault."""
    saved = load_torch(path, "a maze agent file", _MAX_AGENT_BYTES)
    if not isinstance(saved, dict) or saved.get("format") != "structgen maze agent 1":
        raise InputError(f"{path}: not a maze agent file (no 'format': 'structgen maze agent 1')")
    hidden = checked_whole(saved, "hidden", path, 1, MAX_HIDDEN)
    weights = checked_weights(saved, "policy", path)
    way_on = saved.get("way_on", False)  # agents saved before structgen 0.5 had no way on
    if not isinstance(way_on, bool):
        raise InputError(f"{path}: 'way_on' must be true or false, got {way_on!r}")
    policy = MazePolicy(hidden, way_on=way_on)
    try:
        policy.load_state_dict(weights)
    except (RuntimeError, KeyError) as err:
        raise InputError(f"{path}: the weights do not fit the maze agent's network ({one_line(err)})") from None
    return policy.eval(), {k: v for k, v in saved.items() if k not in ("policy", "format")}


def shipped_agent_path() -> Path:
    """``docs/maze_agent.pt`` of a checkout, or the copy installed with the package."""
    import structgen

    checkout = Path(structgen.__file__).resolve().parents[1]  # the folder that holds the package, wherever this module sits
    for candidate in (checkout / "docs" / "maze_agent.pt", Path(__file__).resolve().parent / "maze_agent.pt"):
        if candidate.is_file():
            return candidate
    raise InputError(
        "the shipped maze agent (docs/maze_agent.pt) is not in this installation; give --weights FILE "
        "(problem.agent_weights in a run's configuration)"
    )


def agent_policy(weights: str | Path | None = None) -> MazePolicy:
    """The agent in ``weights``, or the shipped one when none is named."""
    return load_agent(weights or shipped_agent_path())[0]


# --- the run folder -----------------------------------------------------------------------------------------------------------
_TABLE, _HEADER = "agent", "Settings of this maze-agent training (structgen maze train)"


def read_settings(folder: RunFolder) -> AgentSettings:
    return read_training_settings(folder, AgentSettings, _TABLE)


def is_agent_folder(path: str | Path) -> bool:
    return is_training_folder(path, RUN_KIND)


def _open_folder(path: Path, settings: AgentSettings, overwrite: bool) -> RunFolder:
    return open_training_folder(
        path, settings, run_kind=RUN_KIND, domain=DOMAIN, table=_TABLE, header=_HEADER, overwrite=overwrite
    )


def agent_run_summary(run_dir: str | Path) -> dict[str, Any]:
    """What ``structgen info`` says of a training folder: its settings, how far it got, the last held-out test."""
    folder = RunFolder(run_dir)
    settings = read_settings(folder)
    rows = read_history(folder, settings.updates)
    tested = [row["held_out"] for row in rows if row.get("held_out") is not None]
    return {
        "run_dir": str(run_dir),
        "run_kind": RUN_KIND,
        "updates": settings.updates,
        "updates_done": rows[-1]["update"] if rows else 0,
        "agent_steps": rows[-1]["agent_steps"] if rows else 0,
        "held_out": tested[-1] if tested else None,
        "finished": (folder / AGENT_FILE).is_file(),
        "settings": asdict(settings),
    }


def learning_figure(rows: list[dict[str, Any]]) -> Any:
    from evolution.plots import new_figure

    figure = new_figure(figsize=(7, 4))
    axes = figure.add_subplot(1, 1, 1)
    steps = [row["agent_steps"] / 1e6 for row in rows]
    axes.plot(steps, [row["success"] for row in rows], label="training levels (curriculum)", alpha=0.6)
    tested = [row for row in rows if row.get("held_out") is not None]
    axes.plot([r["agent_steps"] / 1e6 for r in tested], [r["held_out"] for r in tested], "o-", label="held-out rooms mazes")
    axes.set_xlabel("agent steps (millions)")
    axes.set_ylabel("episodes that reach the goal")
    axes.set_ylim(0, 1.02)
    axes.grid(alpha=0.3)
    axes.legend(loc="lower right")
    axes.set_title("maze agent: PPO with a PLR/ACCEL curriculum")
    return figure


def _save_checkpoint(folder: RunFolder, ppo: PPO, env: CurriculumMazes, done: int) -> None:
    state = {
        "update": done,
        "policy": ppo.policy.state_dict(),
        "optimiser": ppo.optimiser.state_dict(),
        "mazes": env.env.mazes.state_dict(),
        "memory": env.env.memory.state_dict(),
        "in_play": torch.as_tensor(env.in_play),
        "curriculum": env.curriculum.state_dict(),
        "torch_rng": torch.get_rng_state(),
    }
    save_torch(folder / CHECKPOINT_FILE, state)


def _load_checkpoint(folder: RunFolder, ppo: PPO, env: CurriculumMazes, settings: AgentSettings) -> int:
    """The update the checkpoint was written after, with the training's state restored from it. Every part is
    checked against what a fresh training of the same settings holds before anything is restored, so that a
    damaged or foreign checkpoint is refused naming the field and changes nothing."""
    path = folder / CHECKPOINT_FILE
    state = load_torch(path, "a maze-agent training checkpoint")
    if not isinstance(state, dict):
        raise InputError(f"{path}: not a maze-agent training checkpoint (a {type(state).__name__})")
    done = checked_whole(state, "update", path, 0, settings.updates)
    checked_weights(state, "policy", path)
    checked_optimiser(state, "optimiser", path, list(ppo.policy.parameters()))
    checked_like(env.env.mazes.state_dict(), state.get("mazes"), path, "mazes", varying=("generator",))
    checked_like(env.env.memory.state_dict(), state.get("memory"), path, "memory")
    curriculum = checked_like(env.curriculum.state_dict(), state.get("curriculum"), path, "curriculum", varying=("ids", "levels"))
    known = set(curriculum["ids"].tolist())
    in_play = checked_like(torch.as_tensor(env.in_play), state.get("in_play"), path, "in_play")
    if not set(in_play.tolist()) <= known:
        raise InputError(f"{path}: in_play names levels the curriculum does not hold")
    checked_like(torch.get_rng_state(), state.get("torch_rng"), path, "torch_rng")
    try:
        ppo.policy.load_state_dict(state["policy"])
        ppo.optimiser.load_state_dict(state["optimiser"])
        env.env.mazes.load_state_dict(state["mazes"])
        env.env.memory.load_state_dict(state["memory"])
        env.in_play = [int(i) for i in in_play]
        env.curriculum.load_state_dict(curriculum)
        torch.set_rng_state(state["torch_rng"])
    except Exception as err:  # what the checks above cannot see (a random state torch refuses): name the file
        raise InputError(f"{path}: cannot resume from this checkpoint ({one_line(err)})") from None
    return done


def train_agent(
    run_dir: str | Path, settings: AgentSettings, *, overwrite: bool = False, progress: bool = True
) -> tuple[MazePolicy, list[dict[str, Any]]]:
    """Train (or resume training) the maze agent in ``run_dir``; returns the policy and the history rows."""
    from structgen.devices import resolve_device

    resolve_device(settings.device, "agent device")  # before the folder is made: a refused command leaves nothing
    one = RememberingMazes(
        TorchMazes([random_maze(np.random.default_rng(0), settings.size, "carved")], device="cpu"), way_on=settings.way_on
    )
    check_rollout_memory(one.reset(), settings.envs, settings.steps, what="--envs, --steps and --size")
    with new_folder_removed_on_failure(Path(run_dir), CHECKPOINT_FILE):
        return _train_agent(_open_folder(Path(run_dir), settings, overwrite), settings, progress)


def _train_agent(folder: RunFolder, settings: AgentSettings, progress: bool) -> tuple[MazePolicy, list[dict[str, Any]]]:
    from tqdm import tqdm

    torch.manual_seed(settings.seed)
    curriculum = Curriculum(settings)
    env = CurriculumMazes(curriculum, settings)
    ppo = PPO(MazePolicy(settings.hidden, way_on=settings.way_on), settings)
    done = 0
    with folder.locked():
        checkpoint = folder / CHECKPOINT_FILE
        if checkpoint.exists() or checkpoint.is_symlink():  # a link to a device is refused, not taken for "none"
            done = _load_checkpoint(folder, ppo, env, settings)
            observation = env.env.current()
        else:
            observation = env.env.reset()
        rows = read_history(folder, done)
        write_training_settings(folder, settings, _TABLE, _HEADER)
        held_out = held_out_mazes(settings.size)
        bar = tqdm(total=settings.updates, initial=done, desc="maze agent", unit="update", disable=not progress)
        while done < settings.updates:
            started = time.perf_counter()
            rollout = ppo.collect(env, observation)
            observation = rollout.last
            ppo.advantages(rollout)
            assert rollout.advantages is not None
            curriculum.score(torch.stack(env.log), rollout.advantages, set(env.in_play))
            env.log.clear()
            losses = ppo.update(rollout)
            done += 1
            ended, env.ended = env.ended, []
            row: dict[str, Any] = {
                "update": done,
                "agent_steps": done * settings.envs * settings.steps,
                "episodes": len(ended),
                "success": float(np.mean([r for r, _ in ended])) if ended else None,
                "return": float(np.mean([g for _, g in ended])) if ended else None,
                "buffer": len(curriculum.scores),
                "seconds": time.perf_counter() - started,
                **losses,
            }
            if done % settings.evaluate_every == 0 or done == settings.updates:
                row["held_out"] = run_agent(ppo.policy, held_out, seed=done, device=settings.device).success_rate
                ppo.policy.train()
            rows.append(row)
            bar.update(1)
            bar.set_postfix(success=row["success"], held_out=row.get("held_out"))
            if done % settings.checkpoint_every == 0 or done == settings.updates:
                _save_checkpoint(folder, ppo, env, done)
                write_history(folder, rows, {PLOT_FILE: learning_figure(rows)})
        bar.close()
        save_agent(folder / AGENT_FILE, ppo.policy, settings=asdict(settings), updates=done)
    return ppo.policy, rows
