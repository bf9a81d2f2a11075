"""Time per generation of the stable-structures paper's experiments, from their first generations or from runs.

    python benchmarks/structures_paper_speed.py [--generations 4] [--workers 2] [--experiments baseline cutoff ...]
    python benchmarks/structures_paper_speed.py --runs OUT_DIR [OUT_DIR ...]

The first form runs each experiment's configuration (``configs/paper_<name>.toml``) for a few generations in a
temporary folder; the second reads the metrics of ``structgen structures experiment`` folders. Either way it prints,
per run, the seconds each generation took, the mean integrity and size of the structures it judged (size is what
the cost follows: the collapse screen takes blocks in microseconds, the static analysis a second for a few hundred
vertices), and what the whole budget would take at the measured pace.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from structgen.domains.structures.experiment import EXPERIMENTS, generation_of  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _rows(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]


def _print(name: str, rows: list[dict], budget_generations: int) -> None:
    before = [{"wall_s": 0.0}, *rows]
    seconds = [row["wall_s"] - prior["wall_s"] for prior, row in zip(before, rows)]
    print(f"\n{name}: {len(rows)} generations, {rows[-1]['wall_s']:.0f} s")
    print("| generation | seconds | mean integrity | mean vertices | mean edges |")
    print("|---:|---:|---:|---:|---:|")
    for row, took in zip(rows, seconds):
        print(
            f"| {row['generation']} | {took:.1f} | {row.get('generation_mean_integrity', float('nan')):.3f} | "
            f"{row.get('generation_mean_complexity', float('nan')):.0f} | {row.get('generation_mean_edges', float('nan')):.0f} |"
        )
    later = seconds[1:] or seconds
    pace = statistics.fmean(later)
    print(
        f"At {pace:.1f} s a generation after the first, the paper's budget ({budget_generations} generations) takes "
        f"{(seconds[0] + pace * (budget_generations - 1)) / 60:.0f} min."
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--experiments", nargs="+", choices=list(EXPERIMENTS), default=list(EXPERIMENTS))
    parser.add_argument("--generations", type=int, default=4, help="generations of each timed run")
    parser.add_argument("--workers", type=int, default=2, help="evaluation processes of each timed run")
    parser.add_argument("--runs", nargs="+", metavar="OUT_DIR", help="read these experiment folders instead")
    args = parser.parse_args()
    if args.runs:
        for out in map(Path, args.runs):
            table = json.loads((out / "table.json").read_text())
            for run in table["runs"]:
                _print(run["run"], _rows(Path(run["run"])), table["generations"])
        return
    for name in args.experiments:
        experiment = EXPERIMENTS[name]
        with tempfile.TemporaryDirectory() as scratch:
            run = Path(scratch) / name
            command = [sys.executable, "-m", "structgen", "evolve", str(ROOT / experiment.config), "--run-dir", str(run)]
            command += ["--generations", str(args.generations), "--set", f"run.workers={args.workers}"]
            subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            _print(f"{name} ({args.workers} workers)", _rows(run), generation_of(experiment.spawns))


if __name__ == "__main__":
    main()
