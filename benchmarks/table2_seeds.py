"""Table 2 over training seeds, beside random search: each run's best generator, judged as Table 2 judges.

    python benchmarks/table2_seeds.py RUNS_DIR [--kind even] [--sizes 33x36] [--simulations 5] [--steps 5000]
                                      [--workers 2] [--results PREFIX] [--keep DIR]

RUNS_DIR is the ``--out`` folder of ``benchmarks/random_baseline.py`` run on a warehouse or manufacturing
configuration: ``trained-sS`` (the configuration's optimiser) and ``random-sS`` (random search at the same
evaluations) for each seed S; or a folder that ``--keep`` filled (``trained-sS.npy``, ``random-sS.npy``), so that
the committed generators give the table again without the runs. Each run's best generator by the training objective (its ``best/genome.npy``; for a
CMA-MAE run the result archive's best, the paper's selection) is grown, repaired and simulated with `pbs` at each
size as ``benchmarks/table2.py`` does (200 robots at 33x36, the paper's configuration's 1,000 at 101x102). Prints
the throughput of each (of its runs that do not jam, as Table 2's; 0 when every run jams, the paper's N/A), each side's mean and standard error over seeds,
and the three-standard-error verdict (``evolution.stats``). ``--results PREFIX`` writes PREFIX.json and PREFIX.md;
``--keep DIR`` copies the generators there (``trained-sS.npy``, ``random-sS.npy``: 16 KB each), so that
``benchmarks/table2.py DIR/trained-s0.npy`` repeats a row from committed files.
"""

from __future__ import annotations

import argparse
import platform
import re
import sys
import time
from pathlib import Path

import numpy as np

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
HERE = Path(__file__).resolve().parent
sys.path = [p for p in sys.path if Path(p or ".").resolve() != HERE]

from evolution.files import write_table  # noqa: E402
from evolution.stats import compare, decimals_for, mean_and_standard_error  # noqa: E402


def _table2():
    """benchmarks/table2.py, imported by path (the benchmarks folder is not a package)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("table2", HERE / "table2.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["table2"] = module  # its dataclasses look their module up while being made
    spec.loader.exec_module(module)
    return module


def generators(folder: Path) -> dict[str, np.ndarray]:
    """Each run's best genome by name (``trained-s0``, ``random-s0``, ...): from the run folders where there are
    any, else from the generators a ``--keep`` wrote."""
    pattern = r"(trained|random)-s\d+"
    runs = sorted(p for p in folder.iterdir() if p.is_dir() and re.fullmatch(pattern, p.name))
    if runs:
        return {run.name: np.load(run / "best" / "genome.npy", allow_pickle=False) for run in runs}
    kept = sorted(p for p in folder.glob("*.npy") if re.fullmatch(pattern, p.stem))
    return {path.stem: np.load(path, allow_pickle=False) for path in kept}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=Path, metavar="RUNS_DIR",
                        help="random_baseline.py's --out folder, or a folder --keep filled")  # fmt: skip
    parser.add_argument("--kind", choices=("even", "uneven", "manufacturing"), default="even", help="Table 2's row")
    parser.add_argument("--sizes", default="33x36", help="33x36, 101x102 or both, comma-separated (default 33x36)")
    parser.add_argument("--simulations", type=int, default=5, help="pbs runs per layout (default 5; the paper ran 50)")
    parser.add_argument("--steps", type=int, default=5000, help="steps per run (default 5000, as the paper)")
    parser.add_argument("--workers", type=int, default=2, help="processes that share the runs (default 2)")
    parser.add_argument("--repair-time-limit", type=float, default=120.0, help="seconds for a 101x102 repair")
    parser.add_argument("--results", type=Path, default=None, metavar="PREFIX", help="also write PREFIX.json and .md")
    parser.add_argument("--keep", type=Path, default=None, metavar="DIR", help="copy the generators here")
    args = parser.parse_args()
    table2 = _table2()
    row = table2.ROWS[args.kind]
    if not args.runs.is_dir():
        parser.error(f"{args.runs}: not a folder")
    genomes = generators(args.runs)
    if not genomes:
        parser.error(f"{args.runs}: no trained-sS or random-sS run folders (random_baseline.py's --out) and no "
                     "trained-sS.npy or random-sS.npy (a --keep folder)")  # fmt: skip
    sizes = [size for size in args.sizes.split(",") if size]
    if unknown := [size for size in sizes if size not in ("33x36", "101x102")]:
        parser.error(f"--sizes: {', '.join(unknown)}: Table 2 has 33x36 and 101x102")
    judged: dict[str, dict[str, dict]] = {}
    for name, genome in genomes.items():
        if args.keep is not None:
            from structgen.nca import save_weights

            save_weights(args.keep / f"{name}.npy", genome)
        for size in sizes:
            robots = 200 if size == "33x36" else row.large_robots
            ours = table2.grow_and_repair(genome, row, size, robots, args.repair_time_limit)
            judged.setdefault(size, {})[name] = table2.judge(ours["tiles"], ours["kind"], robots, row, args)
            print(f"{name} at {size}: {table2.cell(judged[size][name])}", flush=True)

    seeds = sorted({int(name.split("-s")[1]) for name in genomes})
    lines = [f"Table 2 ({args.kind}) from each run's best generator, `pbs`, {args.simulations} runs of {args.steps} "
             f"steps (the paper: 50); a generator counts the throughput of its runs that do not jam (Table 2's), 0 when every run jams. {platform.processor() or platform.machine()}, "
             f"{time.strftime('%Y-%m-%d')}.", ""]  # fmt: skip
    report: dict = {"kind": args.kind, "simulations": args.simulations, "steps": args.steps, "seeds": seeds, "sizes": {}}
    for size in sizes:
        lines += [f"| {size} | " + " | ".join(f"seed {s}" for s in seeds) + " | mean ± s.e. |",
                  "|---|" + "---:|" * (len(seeds) + 1)]  # fmt: skip
        sides = {}
        for tag, name in (("trained", "trained (the archive's best)"), ("random", "random search's best")):
            cells = [judged[size].get(f"{tag}-s{s}") for s in seeds]
            values = [0.0 if c is None or c["throughput"] is None else c["throughput"] for c in cells]
            mean, error = mean_and_standard_error(values)
            sides[name] = {"values": values, "mean": mean, "standard_error": error, "runs": cells}
            text = " | ".join("missing" if c is None else table2.cell(c) for c in cells)
            lines.append(f"| {name} | {text} | {mean:.3f} ± {error:.3f} |")
        (ours, theirs) = sides.values()
        compared = compare(ours["values"], theirs["values"])
        decimals = decimals_for([ours["mean"], theirs["mean"]], [ours["standard_error"], theirs["standard_error"]])
        lines += ["", f"{size}: " + compared.sentence("training", "random search", " tasks a step", decimals) + ".", ""]
        report["sizes"][size] = {"methods": sides, "standard_errors": compared.standard_errors, "learns": compared.learns}
    text = "\n".join(lines)
    print(text)
    if args.results is not None:
        write_table(args.results, report, text + "\n")


if __name__ == "__main__":
    main()
