"""Does it learn? The paper's experiment with ga, cma_es and cma_mae on the same evaluation budget.

    python benchmarks/learning.py [--seeds 0 1 2] [--evaluations 8000] [--runs-dir runs/learning]

Each optimiser runs from random NCAs (the paper's network, cutoff 0.5, five steps, building down allowed, growth
capped at 64 vertices) with the fast physics preset, for about ``--evaluations`` evaluations, once per seed. Runs
already present in ``--runs-dir`` with the same configuration are reused (runs are deterministic, so rerunning
them would give the same numbers). Prints a markdown table: best score and its integrity, height and size, and the
tallest structure that stood with no joint broken, with the generation it first appeared.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from structgen.runs import evolve  # noqa: E402
from structgen.runs.experiment import load_experiment  # noqa: E402

# Per-generation batch sizes of the comparison: the paper's population for the GA, a CMA-ES population of 40
# (pycma's default for 4766 parameters would be 29), and five CMA-MAE emitters of 20.
OPTIMIZERS = {
    "ga": (["optimizer.population=100", "optimizer.parents=20"], 100, 80),
    "cma_es": (["optimizer.population=40"], 40, 40),
    "cma_mae": (["optimizer.emitters=5", "optimizer.batch_size=20"], 100, 100),
}


def generations_for(budget: int, first: int, later: int) -> int:
    return 1 + max(0, round((budget - first) / later))


def run_or_reuse(name: str, seed: int, budget: int, runs_dir: Path, workers: int) -> Path:
    overrides, first, later = OPTIMIZERS[name]
    experiment = load_experiment(
        optimizer=name,
        overrides=overrides,
        run_changes={"seed": seed, "generations": generations_for(budget, first, later), "workers": workers},
    )
    folder = runs_dir / f"{name}-s{seed}"
    config = folder / "config.toml"
    metrics = folder / "metrics.jsonl"
    if config.exists() and metrics.exists():
        same = load_experiment(config).with_run(workers=workers) == experiment
        if same and len(metrics.read_text().splitlines()) == experiment.run.generations:
            return folder
    evolve(experiment, folder, overwrite=True)
    return folder


def summarise(folder: Path) -> dict:
    rows = [json.loads(line) for line in (folder / "metrics.jsonl").read_text().splitlines()]
    last = rows[-1]
    tallest = max(row["generation_max_standing_height"] for row in rows)
    first_tall = next(row for row in rows if row["generation_max_standing_height"] == tallest)
    return {
        "evaluations": last["evaluations"],
        "minutes": last["wall_s"] / 60,
        "best": last["best_objective"],
        "integrity": last["best_integrity"],
        "height": last["best_height"],
        "vertices": last["best_complexity"],
        "tallest": tallest,
        "tallest_at": first_tall["evaluations"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="run seeds (default 0 1 2)")
    parser.add_argument("--evaluations", type=int, default=8000, help="evaluation budget per run (default 8000)")
    parser.add_argument("--runs-dir", type=Path, default=Path("runs/learning"), help="where the run folders go")
    parser.add_argument("--workers", type=int, default=2, help="evaluation processes (default 2)")
    args = parser.parse_args()
    print(f"machine: {os.cpu_count()} cores; Python {platform.python_version()}; budget {args.evaluations} evaluations\n")
    print(
        "| optimizer | seed | evaluations | minutes | best Q | its I | its H | its vertices | tallest standing H | first seen at evaluation |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in OPTIMIZERS:
        for seed in args.seeds:
            s = summarise(run_or_reuse(name, seed, args.evaluations, args.runs_dir, args.workers))
            print(
                f"| {name} | {seed} | {s['evaluations']} | {s['minutes']:.1f} | {s['best']:.2f} | {s['integrity']:.3f} "
                f"| {s['height']:.2f} | {s['vertices']:.0f} | {s['tallest']:.2f} | {s['tallest_at']} |"
            )


if __name__ == "__main__":
    main()
