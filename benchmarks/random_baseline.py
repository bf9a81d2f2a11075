"""A configuration's optimiser against random search at the same budget and judge, over seeds: does it learn?

    python benchmarks/random_baseline.py [CONFIG] [--generations N] [--seeds 0 1 2 3 4] [--metric best_objective]
                                         [--out DIR] [--parallel 2] [--results PREFIX]

For each seed, the run of CONFIG (default: the main job, ``structgen evolve``: the paper's GA, 40 genomes, 8
parents, 200 generations, the static judge) and random search (``--optimizer random``), which draws from the
problem's initial distribution as many candidates a generation as CONFIG's optimiser evaluates (the main job:
40, then 32 a generation, 6,408 evaluations each) into the same archive cells where the optimiser keeps one. Each
run in a process of its own with no worker processes, ``--parallel`` at a time. Prints a markdown table of each
seed's final value of every ``--metric`` (a column of the runs' metrics.jsonl: ``best_objective``, ``qd_score``,
``coverage``) and the mean and standard error of each method over the seeds, and whether the optimiser is ahead by
more than three standard errors of the difference (``evolution.stats``). The run folders go to ``--out`` (default:
a temporary folder); a folder that holds a finished run is read, not run again. ``--results PREFIX`` also writes
PREFIX.json and PREFIX.md (each replaced whole, never half-written).

The maze generator at a fifth of a percent of the paper's budget, three seeds a side (about 35 minutes on 2 cores):

    python benchmarks/random_baseline.py configs/maze_cma_mae.toml --generations 20 --seeds 0 1 2 \\
        --metric qd_score coverage --results docs/results/maze-generator-random
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

from evolution.files import write_table  # noqa: E402
from evolution.stats import compare, decimals_for, mean_and_standard_error  # noqa: E402

#: What the JSON results call themselves, so that ``benchmarks/learning_verdicts.py`` finds them.
KIND = "optimiser-against-random-search"

#: The random-search side of every comparison: the evolve options on top of the configuration.
RANDOM = ["--optimizer", "random"]


def _run(folder: Path, command: list[str], metrics_wanted: list[str]) -> dict:
    metrics = folder / "metrics.jsonl"
    if not (metrics.is_file() and (folder / "best" / "best.json").is_file() and _finished(folder)):
        subprocess.run([*command, "--run-dir", str(folder), "--overwrite"], check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)  # fmt: skip
    last = json.loads(metrics.read_text().splitlines()[-1])
    missing = [name for name in metrics_wanted if name not in last]
    if missing:
        raise SystemExit(f"{metrics}: no column {', '.join(missing)} (it has {', '.join(sorted(last))})")
    return {"values": {name: float(last[name]) for name in metrics_wanted}, "evaluations": last["evaluations"],
            "seconds": last["wall_s"]}  # fmt: skip


def _finished(folder: Path) -> bool:
    from structgen.runs.seed_runs import finished

    return finished(folder)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("config", nargs="?", default=None, help="run configuration (default: the main job)")
    parser.add_argument("--generations", type=int, default=None, help="generations a run (default the configuration's)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4], help="run seeds (default 0 to 4)")
    parser.add_argument("--metric", nargs="+", default=["best_objective"],
                        help="metrics.jsonl columns to compare, the first decides the verdict line (default best_objective)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=None, help="folder for the run folders (default: a temporary one)")
    parser.add_argument("--parallel", type=int, default=2, help="runs at once (default 2)")
    parser.add_argument("--results", type=Path, default=None, metavar="PREFIX", help="also write PREFIX.json and PREFIX.md")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="random-baseline-"))
    out.mkdir(parents=True, exist_ok=True)
    base = [sys.executable, "-m", "structgen", "evolve", *([args.config] if args.config else []), "--workers", "0"]
    if args.generations is not None:
        base += ["--generations", str(args.generations)]
    trained = "the main job's GA" if args.config is None else f"{Path(args.config).name}'s optimiser"
    methods = {trained: ("trained", []), "random search": ("random", RANDOM)}
    jobs = {(name, seed): (out / f"{tag}-s{seed}", [*base, "--seed", str(seed), *extra])
            for name, (tag, extra) in methods.items() for seed in args.seeds}  # fmt: skip
    with ThreadPoolExecutor(max_workers=args.parallel) as pool:  # threads only wait on the run processes
        futures = {key: pool.submit(_run, folder, command, args.metric) for key, (folder, command) in jobs.items()}
        results = {key: future.result() for key, future in futures.items()}

    lines = [f"Measured on {platform.processor() or platform.machine()}, Python {platform.python_version()}, "
             f"{args.parallel} run{'s' if args.parallel != 1 else ''} at a time, each in one process; "
             f"`{' '.join(['structgen evolve', *base[4:]])}`, seeds {', '.join(map(str, args.seeds))}.", ""]  # fmt: skip
    report: dict = {
        "kind": KIND,
        "command": " ".join(["structgen evolve", *base[4:]]),
        "config": args.config,
        "generations": args.generations,
        "seeds": args.seeds,
        "metrics": {},
    }
    for metric in args.metric:
        lines += [f"| {metric} | evaluations | " + " | ".join(f"seed {s}" for s in args.seeds) + " | mean ± s.e. |",
                  "|---|---:|" + "---:|" * len(args.seeds) + "---:|"]  # fmt: skip
        summary = {}
        for name in methods:
            values = [results[name, seed]["values"][metric] for seed in args.seeds]
            mean, error = mean_and_standard_error(values)
            evaluations = sorted({results[name, seed]["evaluations"] for seed in args.seeds})
            summary[name] = {"values": values, "mean": mean, "standard_error": error, "evaluations": evaluations}
        (first, second) = summary.values()
        # One precision for the whole metric, so that the two rows' columns read against each other.
        decimals = decimals_for([first["mean"], second["mean"]], [first["standard_error"], second["standard_error"]])
        for name, side in summary.items():
            cells = " | ".join(f"{v:,.{decimals}f}" for v in side["values"])
            spread = f"{side['mean']:,.{decimals}f} ± {side['standard_error']:,.{decimals}f}"
            lines.append(f"| {name} | {', '.join(f'{e:,}' for e in side['evaluations'])} | {cells} | {spread} |")
        compared = compare(first["values"], second["values"])
        lines += ["", f"{metric}: " + compared.sentence(trained, "random search", decimals=decimals) + ".", ""]
        report["metrics"][metric] = {"methods": summary, "difference": compared.difference,
                                     "standard_errors": compared.standard_errors, "learns": compared.learns}  # fmt: skip
    text = "\n".join(lines)
    print(text)
    print(f"Run folders: {out}")
    if args.results is not None:
        write_table(args.results, report, text)


if __name__ == "__main__":
    main()
