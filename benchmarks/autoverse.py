"""Autoverse speed, measured the way the original was measured, beside its numbers.

- env-steps/s: random games (as the original's initial population draws them), one random action per env, a step and
  its observation (view and flat vector) per call, over a batch; 100 steps timed after 5 untimed. On a CPU the engine
  steps with its numba kernel; the tensor-code column is the same engine with ``backend="torch"`` (what runs on GPUs).
  On CUDA the compiled column is the tensor code under ``torch.compile`` (``Engine(..., compile=True)``, compiling
  not timed), and its final maps are checked equal to the uncompiled engine's.
- search: one generation's searches (40 random games, budget 200) in one lockstep call; expansions/s and seconds.
- generation: ``AutoverseProblem.evaluate`` on 40 mutated games at budget 200 (what a generation of the main job
  costs).

    python benchmarks/autoverse.py [--device cuda] [--batches 64 512 2048] [--threads 2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from structgen.domains.autoverse.engine import Engine
from structgen.domains.autoverse.game import mutate_game, random_game
from structgen.domains.autoverse.problem import AutoverseProblem
from structgen.domains.autoverse.search import search

# The original on this 2-core machine (JAX 0.10.2 CPU) and on one H100 (JAX 0.11.2), from the research notes (A11).
ORIGINAL_CPU = {64: 2430, 512: 1634}
ORIGINAL_H100 = {64: 69525, 1024: 509463, 16384: 559237, 65536: 359346}
# The original's search (its best-first search, one game at a time, one thread, pinned to one core), timed in
# alternation with ours by benchmarks/anchors/autoverse.py on 40 random games of budget 200: 206 node expansions a
# second (AMD EPYC 2 vCPU, 2026-11-24). The research notes' 5.4 s per 200-expansion search (37/s), which this file
# divided by before, is five times slower than that. A generation is 40 such searches.
ORIGINAL_SEARCH_PER_S = 206
ORIGINAL_GENERATION_S = 40 * 200 / ORIGINAL_SEARCH_PER_S


def env_steps_per_second(
    batch: int, device: str, observe: bool = True, backend: str = "auto", compile: bool = False
) -> tuple[float, torch.Tensor]:
    """(env-steps/s, the final maps) of 100 timed steps after 5 untimed ones (which also compile, if asked)."""
    rng = np.random.default_rng(batch)
    engine = Engine([random_game(rng) for _ in range(batch)], device=device, backend=backend, compile=compile)
    state = engine.reset()
    actions = torch.as_tensor(rng.integers(0, 5, size=(105, batch)), device=device)
    for i in range(5):
        state, _, _ = engine.step(state, actions[i])
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    started = time.perf_counter()
    for i in range(5, 105):
        state, reward, _ = engine.step(state, actions[i])
        if observe:
            view, flat = engine.observe(state)
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    return 100 * batch / (time.perf_counter() - started), state.map


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cpu", help="torch device (default cpu)")
    parser.add_argument("--batches", type=int, nargs="+", default=[64, 512, 2048], help="batch sizes to time")
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads (default 2)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    original = ORIGINAL_H100 if args.device.startswith("cuda") else ORIGINAL_CPU
    print(
        f"device: {args.device} ({torch.cuda.get_device_name() if args.device.startswith('cuda') else f'{args.threads} CPU threads'})\n"
    )
    cpu = not args.device.startswith("cuda")
    other = "tensor code on CPU" if cpu else "compiled (torch.compile)"
    print(
        f"| batch | env-steps/s, with observations | without | {other}, with observations | original (same device kind) | speed-up, best |"
    )
    print("|---:|---:|---:|---:|---:|---:|")
    for batch in args.batches:
        with_obs, maps = env_steps_per_second(batch, args.device)
        without, _ = env_steps_per_second(batch, args.device, observe=False)
        if cpu:
            other_rate, _ = env_steps_per_second(batch, args.device, backend="torch")
            best = with_obs
        else:
            other_rate, compiled_maps = env_steps_per_second(batch, args.device, compile=True)
            if not torch.equal(maps, compiled_maps):
                raise SystemExit(f"batch {batch}: the compiled engine's maps differ from the uncompiled engine's")
            best = max(with_obs, other_rate)
        theirs = original.get(batch)
        ratio = f"{best / theirs:.0f}x" if theirs else "-"
        print(
            f"| {batch:,} | {with_obs:,.0f} | {without:,.0f} | {other_rate:,.0f} | {f'{theirs:,}' if theirs else '-'} | {ratio} |"
        )

    rng = np.random.default_rng(0)
    games = [random_game(rng) for _ in range(40)]
    search(games[:2], 5, device=args.device)
    started = time.perf_counter()
    results = search(games, 200, list(range(40)), device=args.device)
    seconds = time.perf_counter() - started
    expansions = sum(r.expansions for r in results)
    ours_per_s = expansions / seconds
    print("\n| search (40 games, budget 200) | seconds | expansions/s | original expansions/s | speed-up |")
    print("|---|---:|---:|---:|---:|")
    print(
        f"| lockstep best-first | {seconds:.2f} | {ours_per_s:,.0f} | {ORIGINAL_SEARCH_PER_S} | "
        f"{ours_per_s / ORIGINAL_SEARCH_PER_S:.0f}x |"
    )

    problem = AutoverseProblem()
    children = [mutate_game(g, rng) for g in games]
    genomes = problem.prepare(children, {"budget": 200})
    started = time.perf_counter()
    problem.evaluate(genomes, np.arange(40))
    seconds = time.perf_counter() - started
    print("\n| one generation (40 children, budget 200) | seconds | original seconds | speed-up |")
    print("|---|---:|---:|---:|")
    print(f"| AutoverseProblem.evaluate | {seconds:.2f} | {ORIGINAL_GENERATION_S:.0f} | {ORIGINAL_GENERATION_S / seconds:.0f}x |")


if __name__ == "__main__":
    main()
