"""Speed that holds on a shared machine: each engine at 1 and 2 threads, with the OpenMP threads spinning or sleeping
while they wait, alone and beside a process that keeps one core busy.

Every measurement runs in a fresh interpreter (the wait policy is read when the threading libraries load), its
configurations in alternation so that a noisy neighbour touches all of them alike, and the table gives the median of
``--repeats`` runs:

- autoverse (numba): the engine's CPU kernel, 64 games, a step and its observation, env-steps/s;
- autoverse (torch): the same on the tensor code (what runs on GPUs), env-steps/s;
- fortress (numba): 10 random worlds x 5 seeds x 100 ticks, fortress steps/s;
- growth (torch): the warehouse conv NCA, 20 layouts of 101x102 grown 200 steps (genomes of sd 0.2), layouts/s.

    python benchmarks/threads.py [--repeats 3] [--engines autoverse-numba autoverse-torch fortress growth]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

MEASURE = r"""
import json, sys, time
import structgen  # first, as a user's script would: its thread policy applies only to libraries loaded after it
import numpy as np, numba, torch
threads, engine = int(sys.argv[1]), sys.argv[2]
torch.set_num_threads(threads)
numba.set_num_threads(threads)

def autoverse(backend):
    from structgen.domains.autoverse.engine import Engine
    from structgen.domains.autoverse.game import random_game
    rng = np.random.default_rng(0)
    games = Engine([random_game(rng) for _ in range(64)], backend=backend)
    state, actions = games.reset(), torch.as_tensor(rng.integers(0, 5, size=(105, 64)))
    for i in range(5):
        state, _, _ = games.step(state, actions[i]); games.observe(state)
    began = time.perf_counter()
    for i in range(5, 105):
        state, _, _ = games.step(state, actions[i]); games.observe(state)
    return 100 * 64 / (time.perf_counter() - began)

def fortress():
    from structgen.domains.fortress.engine import simulate
    from structgen.domains.fortress.world import random_world
    rng = np.random.default_rng(0)
    worlds = [random_world(rng) for _ in range(10)]
    simulate(worlds[:2], [0], 5)
    began = time.perf_counter()
    simulate(worlds, range(5), 100)
    return 50 * 100 / (time.perf_counter() - began)

def growth():
    from structgen.domains.layouts.conv_nca import ConvNCA
    from structgen.domains.layouts.kinds import WAREHOUSE
    nca, seed = ConvNCA(3), WAREHOUSE.seed(WAREHOUSE.size("101x102").grown)
    genomes = np.random.default_rng(0).normal(0, 0.2, (20, nca.n_params))
    nca.grow(genomes[:2], seed, 2)
    began = time.perf_counter()
    nca.grow(genomes, seed, 200)
    return 20 / (time.perf_counter() - began)

work = {"autoverse-numba": lambda: autoverse("numba"), "autoverse-torch": lambda: autoverse("torch"),
        "fortress": fortress, "growth": growth}[engine]
print(json.dumps(work()))
"""
ENGINES = {
    "autoverse-numba": "env-steps/s",
    "autoverse-torch": "env-steps/s",
    "fortress": "fortress steps/s",
    "growth": "layouts/s",
}
#: How idle OpenMP threads wait: spinning (OpenMP's default, what structgen did before 0.3) or structgen's default, which
#: is to sleep (``structgen.threads``; the variable is left unset so that structgen sets it).
POLICIES = {"spin": {"OMP_WAIT_POLICY": "ACTIVE"}, "structgen default (sleep)": {}}


def measure(engine: str, threads: int, policy: str, busy: bool) -> float:
    import os

    neighbour = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None
    try:
        time.sleep(0.2)
        env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
        env.update(POLICIES[policy], PYTHONPATH=str(Path(__file__).resolve().parents[1]))
        done = subprocess.run(
            [sys.executable, "-c", MEASURE, str(threads), engine], env=env, capture_output=True, text=True, check=True
        )
        return float(done.stdout.strip().splitlines()[-1])
    finally:
        if neighbour is not None:
            neighbour.kill()
            neighbour.wait()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3, help="runs of each configuration; the median is shown (default 3)")
    parser.add_argument("--engines", nargs="+", default=list(ENGINES), choices=list(ENGINES), help="engines to time")
    args = parser.parse_args()
    configs = [(threads, policy) for policy in POLICIES for threads in (1, 2)]
    print("| engine | unit | threads | waiting threads | alone | beside a busy process |")
    print("|---|---|---:|---|---:|---:|")
    for engine in args.engines:
        results: dict[tuple, list[float]] = {}
        for _ in range(args.repeats):  # in alternation: every configuration sees the same neighbours
            for threads, policy in configs:
                for busy in (False, True):
                    results.setdefault((threads, policy, busy), []).append(measure(engine, threads, policy, busy))
        for threads, policy in configs:
            alone = statistics.median(results[(threads, policy, False)])
            loaded = statistics.median(results[(threads, policy, True)])
            print(f"| {engine} | {ENGINES[engine]} | {threads} | {policy} | {alone:,.0f} | {loaded:,.0f} |", flush=True)


if __name__ == "__main__":
    main()
