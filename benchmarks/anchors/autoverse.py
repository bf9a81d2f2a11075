"""Autoverse's engine: ours beside the original's JAX engine, one step and its observation, in alternation.

    python benchmarks/anchors/autoverse.py --python PATH/TO/JAX/ENV/bin/python [--original PATH]
                                           [--batches 64 512] [--repeats 5] [--core 0]

The original (``smearle/autoverse``) runs ``jit(vmap(env.step_env))``, which returns the observation with the step,
on random games from its own generator (``gen_rand_env_params`` on the evolution config's 16x16 blank game); ours
runs ``Engine.step`` and ``Engine.observe`` on random games from ``random_game``, the same distribution as its
initial population. One random action per game and step, 100 timed steps after an untimed one (which compiles the
original). Both are pinned to one core (``--core``) with one thread, and each repeat times the original (in a
fresh process of the interpreter given by ``--python``, which needs jax, chex, gym, opencv, einops, imageio and
flax: the original's imports) and then ours; the table gives the median of the repeats.

Then the search: the original's best-first search (``search_agent.bfs``, one game at a time, as its evaluation
runs it) and ours (``search``, the games in lockstep) on ``--games`` random games each with a budget of
``--budget`` expansions, in node expansions a second; the original also needs ``fire``, ``gymnax`` and ``distrax``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# Run as a script, this file's folder comes first on sys.path; the repository root must be importable instead.
ROOT = Path(__file__).resolve().parents[2]
sys.path = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from benchmarks.anchors._original import checkout_of_original  # noqa: E402

REPOSITORY = "https://github.com/smearle/autoverse"
ORIGINAL = r"""
import sys, time, warnings
warnings.simplefilter("ignore")
sys.path.insert(0, sys.argv[1])
import jax
from gen_env.configs.config import GenEnvConfig
from gen_env.utils import gen_rand_env_params, init_base_env, init_config
batch = int(sys.argv[2])
cfg = GenEnvConfig()
init_config(cfg)
env, params = init_base_env(cfg)
keys = jax.random.split(jax.random.PRNGKey(0), batch)
games = jax.vmap(lambda key: gen_rand_env_params(cfg, key, env.game_def, params.rules))(keys)
_, state = jax.vmap(env.reset_env)(keys, games)
step = jax.jit(jax.vmap(env.step_env))
actions = jax.random.randint(jax.random.PRNGKey(1), (101, batch), 0, env.num_actions)
out = jax.block_until_ready(step(keys, state, actions[0], games))
state = out[1]
began = time.perf_counter()
for i in range(1, 101):
    out = step(keys, state, actions[i], games)
    state = out[1]
jax.block_until_ready(out)
print(100 * batch / (time.perf_counter() - began))
"""
ORIGINAL_SEARCH = r"""
import contextlib, io, sys, time, warnings
warnings.simplefilter("ignore")
sys.path.insert(0, sys.argv[1])
import jax
from gen_env.configs.config import GenEnvConfig
from gen_env.utils import gen_rand_env_params, init_base_env, init_config
from search_agent import bfs
count, budget = int(sys.argv[2]), int(sys.argv[3])
cfg = GenEnvConfig()
init_config(cfg)
env, params = init_base_env(cfg)
keys = jax.random.split(jax.random.PRNGKey(0), count + 1)
games = [gen_rand_env_params(cfg, key, env.game_def, params.rules) for key in keys]
def expansions(game):
    _, state = env.reset(key=keys[0], params=game)
    with contextlib.redirect_stdout(io.StringIO()):
        found = bfs(env, state, game, max_steps=budget, n_best_to_keep=1)
    return min(found[3], budget)
expansions(games[0])  # compiles
began = time.perf_counter()
total = sum(expansions(game) for game in games[1:])
print(total / (time.perf_counter() - began))
"""


def time_original(python: str, checkout: Path, core: int, program: str, *arguments: int) -> float:
    # One thread for XLA too: its CPU client otherwise starts a pool as wide as the machine.
    env = dict(os.environ, XLA_FLAGS="--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1", JAX_PLATFORMS="cpu")
    done = subprocess.run(
        ["taskset", "-c", str(core), python, "-c", program, str(checkout), *map(str, arguments)],
        capture_output=True,
        text=True,
        env=env,
        cwd=checkout,  # the original reads its palette files from the working folder
    )
    if done.returncode:
        raise SystemExit(f"the original failed under {python}:\n{done.stderr.strip()[-2000:]}")
    return float(done.stdout.strip().splitlines()[-1])


def time_ours(batch: int) -> float:
    import torch

    from structgen.domains.autoverse.engine import Engine
    from structgen.domains.autoverse.game import random_game

    rng = np.random.default_rng(batch)
    engine = Engine([random_game(rng) for _ in range(batch)])
    state, actions = engine.reset(), torch.as_tensor(rng.integers(0, 5, size=(101, batch)))
    state, _, _ = engine.step(state, actions[0])
    engine.observe(state)
    began = time.perf_counter()
    for i in range(1, 101):
        state, _, _ = engine.step(state, actions[i])
        engine.observe(state)
    return 100 * batch / (time.perf_counter() - began)


def search_ours(count: int, budget: int) -> float:
    from structgen.domains.autoverse.game import random_game
    from structgen.domains.autoverse.search import search

    rng = np.random.default_rng(0)
    games = [random_game(rng) for _ in range(count + 1)]
    search(games[:1], 5)
    began = time.perf_counter()
    results = search(games[1:], budget, list(range(count)))
    return sum(r.expansions for r in results) / (time.perf_counter() - began)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--python", required=True, help="an interpreter with the original's imports (jax, chex, gym, ...)")
    parser.add_argument("--original", type=Path, help="a checkout of the original repository (default: clone it)")
    parser.add_argument(
        "--batches", type=int, nargs="*", default=[64, 512], help="games stepped together (default 64 512; none: search only)"
    )
    parser.add_argument("--repeats", type=int, default=5, help="timed runs of each; the median is shown (default 5)")
    parser.add_argument("--core", type=int, default=0, help="the core both run on (default 0)")
    parser.add_argument("--games", type=int, default=40, help="games searched (default 40, a generation)")
    parser.add_argument("--budget", type=int, default=200, help="expansions per game's search (default 200)")
    parser.add_argument("--search-repeats", type=int, default=3, help="timed searches of each; the median is shown (default 3)")
    args = parser.parse_args()
    import numba
    import torch

    os.sched_setaffinity(0, {args.core})
    torch.set_num_threads(1)
    numba.set_num_threads(1)
    with tempfile.TemporaryDirectory(prefix="structgen-anchor-") as scratch:
        checkout = checkout_of_original(args.original, Path(scratch), REPOSITORY, ("gen_env/utils.py",))
        print(f"one step and its observation, 100 steps, one thread each on core {args.core}, median of {args.repeats}")
        print("| batch | original env-steps/s | ours env-steps/s | speed-up |")
        print("|---:|---:|---:|---:|")
        for batch in args.batches:
            theirs, ours = [], []
            for _ in range(args.repeats):
                theirs.append(time_original(args.python, checkout, args.core, ORIGINAL, batch))
                ours.append(time_ours(batch))
            t, o = statistics.median(theirs), statistics.median(ours)
            print(f"| {batch} | {t:,.0f} | {o:,.0f} | {o / t:.0f}x |", flush=True)
        theirs, ours = [], []
        for _ in range(args.search_repeats):
            theirs.append(time_original(args.python, checkout, args.core, ORIGINAL_SEARCH, args.games, args.budget))
            ours.append(search_ours(args.games, args.budget))
        t, o = statistics.median(theirs), statistics.median(ours)
        print(f"\nbest-first search, {args.games} games, budget {args.budget}, median of {args.search_repeats}")
        print("| search | original expansions/s | ours expansions/s | speed-up |")
        print("|---|---:|---:|---:|")
        print(f"| original one game at a time, ours in lockstep | {t:,.0f} | {o:,.0f} | {o / t:.0f}x |")


if __name__ == "__main__":
    main()
