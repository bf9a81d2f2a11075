"""The main job against random search at the same budget and judge: does the GA learn?

    python benchmarks/random_baseline.py [--seeds 0 1 2 3 4] [--out DIR] [--parallel 2]

For each seed, the main job (``structgen evolve``: the paper's GA, 40 genomes, 8 parents, 200 generations, the
static judge) and random search (``--optimizer random``) drawing from the same initial distribution at the GA's
budget: 40 genomes, then 32 a generation (the GA does not evaluate its parents again), 6,408 evaluations each. Each run in a
process of its own with no worker processes, ``--parallel`` at a time. Prints a markdown table of each seed's best
objective and the mean and standard error of each method over the seeds, and whether the GA is ahead by more than
three standard errors of the difference. The run folders go to ``--out`` (default: a temporary folder); a folder
that holds a finished run is read, not run again.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from evolution.stats import Comparison, mean_and_standard_error  # noqa: E402

#: The two methods at one budget: name -> the evolve options on top of the main job.
METHODS = {
    "GA (the main job)": [],
    "random search": ["--optimizer", "random"],
}


def _run(folder: Path, options: list[str], seed: int) -> dict:
    metrics = folder / "metrics.jsonl"
    if not (metrics.is_file() and (folder / "best" / "best.json").is_file() and _finished(folder)):
        command = [sys.executable, "-m", "structgen", "evolve", "--seed", str(seed), "--workers", "0", "--run-dir", str(folder)]
        subprocess.run([*command, *options, "--overwrite"], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rows = [json.loads(line) for line in metrics.read_text().splitlines()]
    return {"best": rows[-1]["best_objective"], "evaluations": rows[-1]["evaluations"], "seconds": rows[-1]["wall_s"]}


def _finished(folder: Path) -> bool:
    from structgen.runs.seed_runs import finished

    return finished(folder)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4], help="run seeds (default 0 to 4)")
    parser.add_argument("--out", type=Path, default=None, help="folder for the run folders (default: a temporary one)")
    parser.add_argument("--parallel", type=int, default=2, help="runs at once (default 2)")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="random-baseline-"))
    out.mkdir(parents=True, exist_ok=True)
    jobs = {
        (name, seed): out / f"{'ga' if name.startswith('GA') else 'random'}-s{seed}" for name in METHODS for seed in args.seeds
    }
    with ThreadPoolExecutor(max_workers=args.parallel) as pool:  # threads only wait on the run processes
        futures = {key: pool.submit(_run, folder, METHODS[key[0]], key[1]) for key, folder in jobs.items()}
        results = {key: future.result() for key, future in futures.items()}

    print(f"Measured on {platform.processor() or platform.machine()}, Python {platform.python_version()}, "
          f"{args.parallel} runs at a time, each in one process.\n")  # fmt: skip
    print("| method | evaluations | " + " | ".join(f"seed {s}" for s in args.seeds) + " | mean ± s.e. |")
    print("|---|---:|" + "---:|" * len(args.seeds) + "---:|")
    summary = {}
    for name in METHODS:
        bests = [results[name, seed]["best"] for seed in args.seeds]
        mean, error = mean_and_standard_error(bests)
        summary[name] = (mean, error)
        evaluations = {results[name, seed]["evaluations"] for seed in args.seeds}
        cells = " | ".join(f"{b:.1f}" for b in bests)
        print(f"| {name} | {', '.join(f'{e:,}' for e in sorted(evaluations))} | {cells} | {mean:.1f} ± {error:.1f} |")
    (ga, ga_error), (random, random_error) = summary.values()
    compared = Comparison(ga, ga_error, random, random_error)
    verdict = "learns" if compared.learns else "is not shown to learn"
    print(f"\nThe GA is ahead by {compared.difference:.1f} ({compared.standard_errors:.1f} standard errors of the difference): "
          f"it {verdict} by the 3-standard-error rule.")  # fmt: skip
    print(f"\nRun folders: {out}")


if __name__ == "__main__":
    main()
