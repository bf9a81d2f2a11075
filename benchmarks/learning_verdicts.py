"""Does each learning result beat random search at its budget? The verdicts, from the committed result tables.

    python benchmarks/learning_verdicts.py [--results docs/results]

Reads the tables the experiments wrote into ``docs/results`` (the stable-structures paper's four experiments and
their ``--optimizer random`` runs in ``structures-paper-table.json``; each Amorphous Fortress experiment's table
beside its random-search table, ``fortress-expN-table.json`` and ``fortress-expN-random-table.json``) and prints,
for each pair, the comparison of :mod:`evolution.stats`: the method's mean and standard error over seeds against
random search's, and whether it is ahead by more than three standard errors of the difference; and each table
``benchmarks/random_baseline.py --results`` wrote there (a configuration's optimiser against random search over
seeds). Runs nothing; an experiment without its random-search table is listed as such.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from evolution.files import MiB, read_json  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
FORTRESS = {"experiment 1 (entities x nodes)": "fortress-exp1", "experiment 2 (entities x entropy)": "fortress-exp2"}


def structures(results: Path) -> list[str]:
    from structgen.domains.structures.experiment import EXPERIMENTS, baseline_markdown, table_key

    if not (results / "structures-paper-table.json").is_file():
        return []
    tables = read_json(results / "structures-paper-table.json", 64 * MiB)
    lines = ["## The stable-structures paper's experiments: the GA against random search", ""]
    for name in EXPERIMENTS:
        baseline = tables.get(table_key(name, "random"))
        if name not in tables:
            continue
        if baseline is None:
            lines += [f"#### {name}: no random-search table yet (`--optimizer random`)", ""]
            continue
        lines.append(baseline_markdown(tables[name], baseline))
    return lines


def fortress(results: Path) -> list[str]:
    from structgen.domains.fortress.experiment import baseline_markdown

    lines = ["## The Amorphous Fortress: MAP-Elites against random search", ""]
    for title, stem in FORTRESS.items():
        ours, theirs = results / f"{stem}-table.json", results / f"{stem}-random-table.json"
        if not ours.is_file():
            continue
        if not theirs.is_file():
            lines += [f"#### {title}: no random-search table yet ({theirs.name})", ""]
            continue
        lines.append(baseline_markdown(read_json(ours, 64 * MiB), read_json(theirs, 64 * MiB)))
    return lines


def against_random(results: Path) -> list[str]:
    """The tables ``benchmarks/random_baseline.py --results`` wrote: a configuration's optimiser against random
    search over seeds, each metric's verdict again from the seeds' values."""
    from evolution.stats import compare, decimals_for

    lines = ["## Runs against random search at the same budget (benchmarks/random_baseline.py)", ""]
    for path in sorted(results.glob("*.json")):
        table = read_json(path, 64 * MiB)
        if not (isinstance(table, dict) and table.get("kind") == "optimiser-against-random-search"):
            continue
        lines.append(f"#### {path.stem}: `{table['command']}`, seeds {', '.join(map(str, table['seeds']))}")
        for metric, row in table["metrics"].items():
            (method, ours), (baseline, theirs) = row["methods"].items()
            decimals = decimals_for([ours["mean"], theirs["mean"]], [ours["standard_error"], theirs["standard_error"]])
            lines.append(
                f"- {metric}: " + compare(ours["values"], theirs["values"]).sentence(method, baseline, decimals=decimals)
            )
        lines.append("")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--results", type=Path, default=ROOT / "docs" / "results", help="the result tables' folder")
    args = parser.parse_args()
    print("\n".join(structures(args.results) + fortress(args.results) + against_random(args.results)))


if __name__ == "__main__":
    main()
