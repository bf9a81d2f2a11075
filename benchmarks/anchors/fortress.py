"""The Amorphous Fortress engine: ours beside the original's Python engine, timed in alternation on the same worlds.

    python benchmarks/anchors/fortress.py [--original PATH] [--worlds 10] [--repeats 3]

Random worlds as the original's QD runs draw them (``random_world``: 15 classes, extra nodes spread over them, 1 to
30 initial entities) are written as fortress files; each runs under seeds 0 to 4 for at most 100 ticks, stopping as
the original's evaluation does (no entities left, inactive, overpopulated). The original runs them as its QD
evaluation does (``Engine`` with its beta configuration, ``importEntityFortDef``, ``rng_sim = default_rng(seed)``,
``resetFortress``, ``update``), ours with ``simulate`` on one numba thread. Each repeat times the original and then
ours in one process; the table gives the median of the repeats for both, the fortress steps each ran (a tick of
one simulation), and the ratio of their speeds.

The original is ``dipikarajesh18/amorphous-fortress``: pass a checkout with ``--original``, or the script clones it
into a scratch folder (network needed). It needs ``pyyaml`` (``pip install 'structgen[anchors]'``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# Run as a script, this file's folder comes first on sys.path; the repository root must be importable instead.
ROOT = Path(__file__).resolve().parents[2]
sys.path = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from benchmarks.anchors._original import checkout_of_original, import_from_original  # noqa: E402
from structgen.domains.fortress.engine import simulate  # noqa: E402
from structgen.domains.fortress.formats import format_fortress  # noqa: E402
from structgen.domains.fortress.world import random_world  # noqa: E402

REPOSITORY = "https://github.com/dipikarajesh18/amorphous-fortress"
SEEDS = range(5)
TICKS = 100


def original_runner(checkout: Path):
    """A function that runs one fortress file under every seed with the original's engine; returns the ticks run."""
    engine_module = import_from_original(checkout, "engine")
    config = str(checkout / "CONFIGS" / "beta_config.yaml")

    def run(path: Path) -> int:
        with contextlib.redirect_stdout(io.StringIO()):
            engine = engine_module.Engine(config, init_seed=0)
            engine.fortress.importEntityFortDef(str(path))
            engine.recordState()
            ticks = 0
            for seed in SEEDS:
                engine.fortress.rng_sim = np.random.default_rng(seed)
                engine.resetFortress()
                fortress = engine.fortress
                loops = 0
                while not (fortress.terminate() or fortress.inactive() or fortress.overpop() or loops >= TICKS):
                    engine.update(True)
                    loops += 1
                ticks += loops
        return ticks

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--original", type=Path, help="a checkout of the original repository (default: clone it)")
    parser.add_argument("--worlds", type=int, default=10, help="random worlds (default 10; the original takes ~10 s each)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each; the median is shown (default 3)")
    args = parser.parse_args()
    import numba

    numba.set_num_threads(1)
    rng = np.random.default_rng(0)
    worlds = [random_world(rng) for _ in range(args.worlds)]
    with tempfile.TemporaryDirectory(prefix="structgen-anchor-") as scratch:
        scratch = Path(scratch)
        run_original = original_runner(
            checkout_of_original(args.original, scratch, REPOSITORY, ("engine.py", "CONFIGS/beta_config.yaml"))
        )
        paths = []
        for index, world in enumerate(worlds):
            paths.append(scratch / f"world_{index}.txt")
            paths[-1].write_text(format_fortress(world))
        simulate(worlds[:1], [0], 5)  # compile ours
        os.chdir(scratch)  # the original may write logs where it runs
        times: dict[str, list[float]] = {"original": [], "ours": []}
        for _ in range(args.repeats):
            began = time.perf_counter()
            theirs = sum(run_original(path) for path in paths)
            times["original"].append(time.perf_counter() - began)
            began = time.perf_counter()
            mine = int(simulate(worlds, SEEDS, TICKS).ticks.sum())
            times["ours"].append(time.perf_counter() - began)
    theirs_s, ours_s = statistics.median(times["original"]), statistics.median(times["ours"])
    print(f"{args.worlds} random worlds x {len(SEEDS)} seeds x at most {TICKS} ticks, one thread each, median of {args.repeats}")
    print("| engine | fortress steps | seconds | fortress steps/s | speed-up |")
    print("|---|---:|---:|---:|---:|")
    print(f"| original (Python) | {theirs:,} | {theirs_s:.2f} | {theirs / theirs_s:,.0f} | 1x |")
    print(
        f"| structgen (numba) | {mine:,} | {ours_s:.4f} | {mine / ours_s:,.0f} | {(mine / ours_s) / (theirs / theirs_s):,.0f}x |"
    )


if __name__ == "__main__":
    main()
