"""Re-derive the indexed results from the committed files, at a reduced and stated scale.

    python benchmarks/results_check.py [--cheap] [--only ID [ID ...]] [--keep DIR] [--json OUT.json]

Each check below stands for a claim of ``docs/results/README.md`` (its ``id`` is the claim's anchor there). It runs
the claim's own commands (``structgen ...``, as a user would) on the committed weights, layouts and configurations,
at the scale its ``scale`` states, and compares the number it gets with the number that scale gave when the check
was last recorded. A change to the code that moves a number beyond its tolerance fails the check, and the script
exits 1: the claim then has to be measured again at full scale before its number is kept. The numbers at reduced
scale are not the claims' (the index gives those); they only tell that the code still makes them.

``--cheap`` runs the checks that take seconds (CI runs these, ``make results-check`` runs all). A check that needs
the papers' reference data (``$STRUCTGEN_REFERENCE_DATA``) is skipped, saying so, where it is absent. Every command
runs in a scratch folder (``--keep`` keeps it).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

ROOT = Path(__file__).resolve().parent.parent
PAPER_EVEN_101X102 = (
    "warehouse-maps/warehouse/ours/nca_to_show/xxlarge_maps/iter=200/"
    "kiva_xxlarge_cma-mae_global_opt_repaired_one_endpt_throughput-hamming_a=5.json"
)


class CheckFailed(RuntimeError):
    """A command of a check did not run through (its exit status and last line of error)."""


def structgen(*args: object, cwd: Path) -> str:
    """Run ``structgen ARGS`` in ``cwd`` (the project's commands, as the index gives them); its standard output."""
    command = [sys.executable, "-m", "structgen", *map(str, args)]
    done = subprocess.run(command, cwd=cwd, capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or [f"exit {done.returncode}"])[-1]
        raise CheckFailed(f"structgen {' '.join(map(str, args))}: {last}")
    return done.stdout


def _info(run_dir: Path, cwd: Path) -> dict:
    return json.loads(structgen("info", run_dir, "--json", cwd=cwd))


def main_job(work: Path, optimizer: str = "ga") -> float:
    run = work / f"main-{optimizer}"
    structgen("evolve", "--generations", 20, "--seed", 0, "--workers", 0, "--optimizer", optimizer, "--run-dir", run, cwd=work)
    return float(_info(run, work)["best"]["objective"])


def even_generator_33x36(work: Path) -> float:
    weights = ROOT / "docs/layout_runs/even_generator.npy"
    structgen("warehouse", "grow", "--weights", weights, "-o", work / "even.json", cwd=work)
    structgen("warehouse", "repair", work / "even.json", "-o", work / "even_repaired.json", cwd=work)
    judged = structgen(
        "warehouse", "evaluate", work / "even_repaired.json", "--agents", 200, "--simulations", 2, "--steps", 1000,
        "--planner", "pbs", "--workers", 1, "--json", cwd=work,
    )  # fmt: skip
    return float(json.loads(judged)["throughput_mean"])


def fortress_run(work: Path) -> float:
    run = work / "fortress"
    structgen(
        "evolve", ROOT / "configs/fortress_paper.toml", "--seed", 20, "--generations", 300, "--workers", 0,
        "--set", "problem.measures=entities_nodes", "--run-dir", run, cwd=work,
    )  # fmt: skip
    return float(_info(run, work)["archive"]["qd_score"])


def cutoff_first_standing(work: Path) -> float:
    table = structgen(
        "structures", "experiment", "cutoff", work / "cutoff", "--seeds", 0, "--spawns", 180, "--workers", 0, "--json",
        cwd=ROOT,  # the experiment's configuration is configs/paper_cutoff.toml, relative to the project
    )  # fmt: skip
    first = json.loads(table)["runs"][0]["first_standing_with_edges_spawn"]
    return math.nan if first is None else float(first)


def maze_generator_qd(work: Path) -> float:
    run = work / "maze"
    structgen("evolve", ROOT / "configs/maze_cma_mae.toml", "--seed", 0, "--generations", 3, "--workers", 0, "--run-dir", run,
              cwd=work)  # fmt: skip
    return float(_info(run, work)["archive"]["qd_score"])


def maze_agent_rooms(work: Path) -> float:
    tested = structgen("maze", "test-agent", "--kind", "rooms", "--count", 20, "--json", cwd=work)
    return float(json.loads(tested)["success_rate"])


def nine_levels(work: Path) -> float:
    weights = ROOT / "docs/tall_grown_9.npy"
    structgen("grow", "--weights", weights, "--max-extent", 8, "--iterations", 8, "-o", work / "nine.json", cwd=work)
    return float(json.loads(structgen("info", work / "nine.json", "--json", cwd=work))["vertices"])


def autoverse_best_game_reseeded(work: Path) -> float:
    game = ROOT / "docs/results/autoverse-games/trained-s0.json"
    searched = structgen("autoverse", "evaluate", game, "--budget", 4000, "--seed", 1, "--json", cwd=work)
    return float(json.loads(searched)["fitness"])


def pbs_paper_even_101x102(work: Path) -> float:
    layout = Path(os.environ["STRUCTGEN_REFERENCE_DATA"]) / PAPER_EVEN_101X102
    judged = structgen(
        "warehouse", "evaluate", layout, "--agents", 1400, "--simulations", 1, "--steps", 200, "--planner", "pbs",
        "--workers", 1, "--json", cwd=work,
    )  # fmt: skip
    return float(json.loads(judged)["throughput_mean"])


@dataclass(frozen=True)
class Check:
    """One indexed claim re-derived at a reduced scale: what it ran, what that gave when recorded, how far it may
    move (absolute), and whether it is cheap (seconds) and needs the papers' reference data."""

    id: str
    scale: str
    run: Callable[[Path], float]
    expected: float
    tolerance: float
    cheap: bool = True
    reference: bool = False


CHECKS = (
    Check("main-job", "the GA, seed 0, 20 of 200 generations (648 evaluations): best Q", main_job, 64.0, 0.5),
    Check(
        "main-job-random",
        "random search, seed 0, 20 generations at the GA's budget (648 evaluations): best Q",
        lambda work: main_job(work, "random"),
        44.169,
        0.5,
    ),
    Check(
        "table2-even-33x36",
        "even_generator.npy grown at 33x36, repaired, 200 robots, 2 pbs runs of 1,000 steps: mean throughput",
        even_generator_33x36,
        6.673,
        0.05,
    ),
    Check(
        "fortress-exp1",
        "one run of configs/fortress_paper.toml (entities_nodes), seed 20, 300 of 10,000 generations: QD score",
        fortress_run,
        132.96,
        2.0,
    ),
    Check(
        "structures-cutoff",
        "the cutoff experiment, seed 0, 180 of 5,800 spawns: first spawn with a structure standing whole",
        cutoff_first_standing,
        100.0,
        0.0,
    ),
    Check(
        "maze-generator",
        "configs/maze_cma_mae.toml, seed 0, 3 of 667 generations (450 evaluations): QD score",
        maze_generator_qd,
        56.0,
        0.0,
    ),
    Check("maze-agent", "the shipped maze agent on 20 rooms mazes of 16x16: success rate", maze_agent_rooms, 1.0, 0.05),
    Check("tall-nine", "docs/tall_grown_9.npy grown 8 steps at extent 8: vertices", nine_levels, 353.0, 0.0),
    Check(
        "autoverse-games",
        "the GA's best game of seed 0 searched at budget 4,000 under child order 1 (one of the table's five): fitness",
        autoverse_best_game_reseeded,
        2317.0,
        0.0,
    ),
    Check(
        "pbs-paper-101x102",
        "the paper's even 101x102 layout, 1,400 robots, one pbs run of 200 of 5,000 steps: throughput",
        pbs_paper_even_101x102,
        14.74,
        0.2,
        cheap=False,
        reference=True,
    ),
)


def verdict(check: Check, value: float) -> bool:
    """Whether ``value`` is where the check was recorded: within its tolerance (NaN only where NaN was recorded)."""
    if math.isnan(check.expected) or math.isnan(value):
        return math.isnan(check.expected) and math.isnan(value)
    return abs(value - check.expected) <= check.tolerance + 1e-9


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cheap", action="store_true", help="only the checks that take seconds (what CI runs)")
    parser.add_argument("--only", nargs="+", metavar="ID", choices=[c.id for c in CHECKS], help="only these checks")
    parser.add_argument("--keep", type=Path, default=None, metavar="DIR", help="run in DIR and keep what the checks wrote")
    parser.add_argument("--json", type=Path, default=None, metavar="OUT.json", help="also write the results as JSON")
    args = parser.parse_args()
    chosen = [c for c in CHECKS if (not args.cheap or c.cheap) and (not args.only or c.id in args.only)]
    scratch = args.keep or Path(tempfile.mkdtemp(prefix="results-check-"))
    scratch.mkdir(parents=True, exist_ok=True)
    print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, {time.strftime('%Y-%m-%d')}\n")
    print("| claim | reduced scale | recorded | now | tolerance | seconds | verdict |")
    print("|---|---|---:|---:|---:|---:|---|")
    results, failed = [], 0
    for check in chosen:
        work = scratch / check.id
        work.mkdir(exist_ok=True)
        began = time.perf_counter()
        if check.reference and not os.environ.get("STRUCTGEN_REFERENCE_DATA"):
            value, outcome = math.nan, "skipped: needs the papers' reference data ($STRUCTGEN_REFERENCE_DATA)"
        else:
            try:
                value = check.run(work)
                outcome = "holds" if verdict(check, value) else "MOVED"
            except CheckFailed as err:
                value, outcome = math.nan, f"FAILED: {err}"
        failed += outcome.startswith(("MOVED", "FAILED"))
        seconds = time.perf_counter() - began
        results.append({"id": check.id, "scale": check.scale, "recorded": check.expected, "now": value, "verdict": outcome})
        print(
            f"| [{check.id}](../docs/results/README.md#{check.id}) | {check.scale} | {check.expected:g} | {value:g} | "
            f"{check.tolerance:g} | {seconds:.0f} | {outcome} |",
            flush=True,
        )
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1) + "\n")
    if args.keep is None:
        shutil.rmtree(scratch, ignore_errors=True)
    print(f"\n{len(chosen) - failed} of {len(chosen)} checks hold" + (f"; {failed} moved or failed" if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
