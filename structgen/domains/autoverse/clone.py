"""Behaviour cloning on the playtraces of an evolution run, evaluated as the original evaluates it.

- Data: the best playtrace of every distinct game the run evaluated (:func:`collect_playtraces`), games with fitness
  below 2 left out, split as the original splits them (sorted by fitness; every 10th from the first to validation,
  every 10th from the tenth to test, the rest to training).
- Observations: the view around the player (a 5, 10 or 20 square, or the full 31x31) and the flat vector (facing,
  rules, rewards; rules zeroed with ``hide_rules``). Each observation is paired with the action taken from it; the
  original pairs it with the action that led to it (``original_pairing``).
- Network: the original's ``ConvForward``: a 7x7 stride-2 convolution (256 channels) over the view, flattened and
  joined with a 256-unit layer over the flat vector, two more 256-unit layers, a policy head and a value head. The
  original also computes a second convolution whose output it throws away; it is left out here (no effect on
  outputs).
- Loss: -log pi(a|s); Adam (eps 1e-5) with the gradient norm clipped at 0.5; batches drawn uniformly.
- Evaluation: each game played for ``eval_steps`` steps (the original: 10,000, about 99 episodes) with actions
  sampled from the policy, the score being the sum of the original's normalised reward (:func:`normalisation`).
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from structgen.budget import check_memory
from structgen.devices import resolve_device
from structgen.domains.autoverse.engine import EPISODE_STEPS, VIEW, Engine, Mechanics, Observation
from structgen.domains.autoverse.game import check_game, game_key
from structgen.domains.autoverse.train_settings import CloneSettings
from structgen.errors import InputError

__all__ = [
    "CloneSettings",
    "EvaluationGames",
    "Policy",
    "clone_run",
    "collect_playtraces",
    "evaluate_policy",
    "fit_policy",
    "normalisation",
    "split",
]


class Policy(nn.Module):
    """The original's ``ConvForward`` (without its unused second convolution): logits over 5 actions and a value."""

    def __init__(self, flat_size: int = 1811, hidden: int = 256, view: int = 31) -> None:
        super().__init__()
        self.conv = nn.Conv2d(5, hidden, kernel_size=7, stride=2)
        side = (view - 7) // 2 + 1
        self.flat = nn.Linear(flat_size, hidden)
        self.body = nn.Sequential(
            nn.Linear(hidden * side * side + hidden, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU()
        )
        self.policy = nn.Linear(hidden, 5)
        self.value = nn.Linear(hidden, 1)
        nn.init.orthogonal_(self.policy.weight, 0.01)
        nn.init.zeros_(self.policy.bias)
        nn.init.orthogonal_(self.value.weight, 1.0)
        nn.init.zeros_(self.value.bias)

    def forward(self, view: torch.Tensor, flat: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        seen = torch.relu(self.conv(view.float())).flatten(1)
        joined = torch.cat([seen, torch.relu(self.flat(flat.float()))], dim=1)
        hidden = self.body(joined)
        return self.policy(hidden), self.value(hidden).squeeze(-1)


# -- data -------------------------------------------------------------------------------------------------------------------
#: A playtrace file larger than this (compressed, or unpacked) is refused before it is read.
MAX_PLAYTRACE_BYTES = 512 << 20
_TRACE_ARRAYS = ("rules", "rewards", "map", "actions", "fitness", "best_return")


def read_playtraces(path: Path) -> dict[str, np.ndarray]:
    """One ``playtraces/gen-*.npz`` file, checked: read through the file gate (a FIFO or a device is refused, never
    waited on), numbers only (no pickled objects), every array present with one row per game, every game a valid
    game (:func:`.game.check_game`), actions and scores in range. A bad file is an InputError naming it and what is
    wrong, before any training."""
    import io
    import zipfile

    from evolution.files import read_bytes
    from structgen.budget import check_memory
    from structgen.errors import InputError

    raw = read_bytes(path, MAX_PLAYTRACE_BYTES)
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as archive:
            unpacked = sum(member.file_size for member in archive.infolist())
        check_memory(unpacked, f"{path} unpacked")
        with np.load(io.BytesIO(raw), allow_pickle=False) as data:
            missing = [name for name in _TRACE_ARRAYS if name not in data.files]
            if missing:
                raise InputError(f"{path}: not a playtrace file (it lacks {', '.join(missing)})")
            arrays = {name: data[name] for name in _TRACE_ARRAYS}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as err:
        raise InputError(f"{path}: not a playtrace file ({err})") from None
    counts = {name: len(array) if array.ndim else -1 for name, array in arrays.items()}
    if len(set(counts.values())) != 1 or -1 in counts.values():
        raise InputError(f"{path}: its arrays hold different numbers of games ({counts})")
    for name, array in arrays.items():
        if not np.issubdtype(array.dtype, np.number):
            raise InputError(f"{path}: {name} holds {array.dtype}, not numbers")
    actions, scores = arrays["actions"], np.concatenate([arrays["fitness"].ravel(), arrays["best_return"].ravel()])
    if actions.ndim != 2 or ((actions < -1) | (actions > 4)).any():
        raise InputError(f"{path}: actions must be a table of -1 (none) and 0 to 4, one row per game")
    if not np.isfinite(scores).all():
        raise InputError(f"{path}: fitness and best_return must be finite numbers")
    for i in range(counts["fitness"]):
        check_game({key: arrays[key][i] for key in ("rules", "rewards", "map")}, f"{path}, game {i}")
    return arrays


def collect_playtraces(run_dir: Path, min_fitness: float = 2.0) -> list[dict[str, Any]]:
    """Every distinct game of the run's ``playtraces/`` with its best trace (highest return; the later generation
    on ties), those with fitness of at least ``min_fitness``."""
    from structgen.domains.autoverse.problem import PLAYTRACES

    files = sorted((Path(run_dir) / PLAYTRACES).glob("gen-*.npz"))
    if not files:
        raise FileNotFoundError(f"{run_dir}: no {PLAYTRACES}/gen-*.npz (not an Autoverse run, or no generation yet)")
    best: dict[str, dict[str, Any]] = {}
    for path in files:
        data = read_playtraces(path)
        for i in range(len(data["fitness"])):
            game = {key: data[key][i] for key in ("rules", "rewards", "map")}
            entry = {
                **game,
                "actions": data["actions"][i][data["actions"][i] >= 0],
                "fitness": float(data["fitness"][i]),
                "best_return": float(data["best_return"][i]),
            }
            key = game_key(game)
            if key not in best or entry["best_return"] >= best[key]["best_return"]:
                best[key] = entry
    return [entry for entry in best.values() if entry["fitness"] >= min_fitness]


def split(entries: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """The original's split: sorted by fitness, index % 10 == 0 to val, == 9 to test, the rest to train."""
    ordered = sorted(entries, key=lambda e: e["fitness"])
    parts: dict[str, list[dict[str, Any]]] = {"train": [], "val": [], "test": []}
    for index, entry in enumerate(ordered):
        parts["val" if index % 10 == 0 else "test" if index % 10 == 9 else "train"].append(entry)
    return parts


def transitions(
    entries: list[dict[str, Any]], observation: Observation, *, original_pairing: bool = False, device: str = "cpu"
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``(views, flats, actions)`` of every step of the traces, replayed in lockstep."""
    engine = Engine(entries, device=device)
    state = engine.reset()
    length = max(len(e["actions"]) for e in entries)
    actions = torch.full((len(entries), length), -1, dtype=torch.int64)
    for row, entry in enumerate(entries):
        actions[row, : len(entry["actions"])] = torch.as_tensor(entry["actions"], dtype=torch.int64)
    actions = actions.to(engine.device)
    views, flats, taken = [], [], []
    for t in range(length):
        valid = actions[:, t] >= 0
        before = engine.observe(state, observation)
        state, _, _ = engine.step(state, actions[:, t].clamp(min=0))
        view, flat = engine.observe(state, observation) if original_pairing else before
        views.append(view[valid])
        flats.append(flat[valid])
        taken.append(actions[valid, t])
    return torch.cat(views), torch.cat(flats), torch.cat(taken)


def normalisation(
    engine: Engine, seed: int = 0, original: bool = False, random_episodes: int = 8
) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-game reward normalisation ``(bias, scale)``; a step's normalised reward is ``(reward + bias / 100) *
    scale``.

    The original's: its "random" baseline is one action, drawn once and repeated (it samples inside a traced loop);
    ``bias`` is minus that baseline's mean reward per step; ``scale`` is 1 / (max - min) of {the return of turning
    for one episode, the baseline's largest one-step reward}, 1 where they are equal (the turning return here is
    over a whole episode of 101 steps; the original's scan runs 100).

    With ``original=False`` (the default) the returns of ``random_episodes`` episodes of uniformly random actions join
    that set. Without them, a game where neither baseline earns anything keeps scale 1 and its raw rewards pass
    through: in a game of the main job's run whose rules cascade once force is placed, one episode of random play
    earned -22,639, which dominated the mean of every policy's validation return (issue 43). One random episode is
    not always enough: in a game of a 100-generation run one seed of four missed the cascade, and that game alone
    pulled a 200-game validation mean from about 2 to -7."""
    count = engine.n_games
    steps = EPISODE_STEPS + 1
    rng = np.random.default_rng(seed)
    constant = torch.as_tensor(rng.integers(0, 5, size=count), device=engine.device)
    totals, largest, turning = [torch.zeros(count, device=engine.device) for _ in range(3)]
    largest -= float("inf")
    state, turn = engine.reset(), engine.reset()
    # Episodes are deterministic, so one episode of each stands for all of them.
    for _ in range(steps):
        state, reward, _ = engine.step(state, constant)
        totals += reward
        largest = torch.maximum(largest, reward)
        turn, reward, _ = engine.step(turn, torch.zeros(count, dtype=torch.int64, device=engine.device))
        turning += reward
    bias = -(totals / steps)
    high, low = torch.maximum(turning, largest), torch.minimum(turning, largest)
    if not original:
        played = _random_returns(engine, random_episodes, rng).view(random_episodes, count)
        high, low = torch.maximum(high, played.max(dim=0).values), torch.minimum(low, played.min(dim=0).values)
    spread = high - low
    scale = torch.where(spread == 0, torch.ones_like(spread), 1.0 / spread)
    return bias, scale


def _random_returns(engine: Engine, episodes: int, rng: np.random.Generator) -> torch.Tensor:
    """``(episodes * games,)``: the return of each game's ``episodes`` episodes of uniformly random actions, played
    together (rows ``e * games + g``)."""
    games = torch.arange(engine.n_games, device=engine.device).repeat(episodes)
    state = engine.reset(games)
    total = torch.zeros(len(games), device=engine.device)
    for _ in range(EPISODE_STEPS + 1):
        actions = torch.as_tensor(rng.integers(0, 5, size=len(games)), device=engine.device)
        state, reward, _ = engine.step(state, actions)
        total += reward
    return total


class EvaluationGames:
    """Games made ready for :func:`evaluate_policy` (their engine and normalisation, the normalisation drawn from
    ``seed``), for evaluating more than once without building them again."""

    def __init__(self, entries: list[dict[str, Any]], seed: int = 0, device: str = "cpu") -> None:
        self.engine = Engine(entries, device=device, mechanics=Mechanics())
        self.bias, self.scale = normalisation(self.engine, seed)


@torch.no_grad()
def evaluate_policy(
    policy: Policy,
    entries: list[dict[str, Any]] | EvaluationGames,
    observation: Observation,
    steps: int,
    seed: int = 0,
    device: str = "cpu",
    progress: str | None = None,
) -> np.ndarray:
    """Sum of normalised reward over ``steps`` steps of each game (episodes restart where they end), actions sampled
    from the policy; ``progress`` names a progress bar on standard error (None: none). ``entries`` are games, made
    ready here with ``seed`` and ``device``, or :class:`EvaluationGames` made before."""
    from tqdm import tqdm

    ready = entries if isinstance(entries, EvaluationGames) else EvaluationGames(entries, seed, device)
    engine, bias, scale = ready.engine, ready.bias, ready.scale
    generator = torch.Generator(device=engine.device).manual_seed(seed)
    state, start = engine.reset(), engine.reset()
    total = torch.zeros(engine.n_games, device=engine.device)
    for _ in tqdm(range(steps), desc=progress, disable=progress is None, leave=False):
        logits, _ = policy(*engine.observe(state, observation))
        action = torch.multinomial(torch.softmax(logits, dim=1), 1, generator=generator).squeeze(1)
        state, reward, done = engine.step(state, action)
        total += (reward + bias / EPISODE_STEPS) * scale
        state = state.where(done, start)
    return total.cpu().numpy()


def fit_policy(
    policy: Policy,
    views: torch.Tensor,
    flats: torch.Tensor,
    actions: torch.Tensor,
    steps: int,
    batch_size: int,
    learning_rate: float,
    seed: int,
    progress: bool = True,
) -> list[float]:
    """Behaviour cloning: ``steps`` Adam steps (eps 1e-5, gradient norm clipped at 0.5, the original's) on
    -log pi(a|s) over batches drawn uniformly from the transitions; returns the loss of every step."""
    from tqdm import tqdm

    optimiser = torch.optim.Adam(policy.parameters(), lr=learning_rate, eps=1e-5)
    generator = torch.Generator(device=views.device).manual_seed(seed)
    losses = []
    policy.train()
    for _ in tqdm(range(steps), desc="clone", disable=not progress):
        batch = torch.randint(len(actions), (batch_size,), generator=generator, device=views.device)
        logits, _ = policy(views[batch], flats[batch])
        loss = nn.functional.cross_entropy(logits, actions[batch])
        optimiser.zero_grad()
        loss.backward()
        nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
        optimiser.step()
        losses.append(float(loss.detach()))
    return losses


def clone_run(run_dir: Path, settings: CloneSettings, output: Path, *, progress: bool = True) -> dict[str, Any]:
    """Train a policy on the run's playtraces, evaluate it on every split, write ``policy.pt`` and ``report.json``."""
    from evolution.files import atomic_write
    from structgen.runs.training_folder import save_torch

    output = Path(output)
    if output.exists() and not output.is_dir():
        raise InputError(f"{output}: is a file; clone writes a folder (policy.pt, report.json)")
    if output.is_dir() and {p.name for p in output.iterdir()} - {"policy.pt", "report.json"}:
        raise InputError(f"{output}: holds other files; clone writes into a new folder or one it wrote before")
    resolve_device(settings.device, "clone device")  # a GPU that is not there: refused before the data is read
    torch.manual_seed(settings.seed)
    parts = split(collect_playtraces(run_dir, settings.min_fitness))
    if not parts["train"]:
        raise InputError(f"{run_dir}: no game with fitness >= {settings.min_fitness} to learn from")
    observation = settings.observation()
    # Every step's view and flat observation is kept for the fit (and copied once as it is gathered).
    steps = sum(len(entry["actions"]) for entry in parts["train"])
    check_memory(steps * (5 * VIEW * VIEW + 1811 + 8) * 2, f"{steps:,} observed steps of {len(parts['train']):,} games")
    views, flats, actions = transitions(
        parts["train"], observation, original_pairing=settings.original_pairing, device=settings.device
    )
    policy = Policy(hidden=settings.hidden).to(settings.device)
    losses = fit_policy(
        policy, views, flats, actions, settings.steps, settings.batch_size, settings.learning_rate, settings.seed, progress
    )
    policy.eval()
    report: dict[str, Any] = {
        "settings": asdict(settings),
        "transitions": len(actions),
        "final_loss": float(np.mean(losses[-50:])),
    }
    for name, entries in parts.items():
        if not entries:
            continue
        label = f"evaluate on {len(entries)} {name} games" if progress else None
        returns = evaluate_policy(policy, entries, observation, settings.eval_steps, settings.seed, settings.device, label)
        report.update(
            {
                f"{name}_games": len(entries),
                f"{name}_mean": float(returns.mean()),
                f"{name}_min": float(returns.min()),
                f"{name}_max": float(returns.max()),
                f"{name}_std": float(returns.std()),
            }
        )
    output.mkdir(parents=True, exist_ok=True)
    save_torch(output / "policy.pt", policy.state_dict())
    atomic_write(output / "report.json", json.dumps(report, indent=2) + "\n")
    return report
