"""The paper's two experiments end to end: ten MAP-Elites runs, one per seed, then Table 3 from their archives.

``structgen fortress experiment entities_nodes OUT`` runs ``configs/fortress_paper.toml`` (or ``--config``) under
seeds 20 to 29 (the original's sweep), each in its own run folder ``OUT/seed-<S>``, several at a time on local cores
or on a Dask cluster; a run folder that exists is resumed or, when finished, kept. Then every run's archive is
re-evaluated as the paper's Table 3 does (:func:`.robustness.reevaluate`: as evolved, on 5 new seeds, on new seeds
with 5 times longer episodes; each run re-binned, the runs merged best-per-cell) and the table is written beside
the paper's numbers: ``OUT/table.json`` (every row) and ``OUT/table.md``.

A run is a separate ``structgen evolve`` / ``structgen resume`` process, so runs in parallel share nothing but the
disk, a killed experiment resumes run by run, and a Dask worker needs only the package and the output folder.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from evolution.files import write_table
from structgen.errors import InputError
from structgen.runs.seed_runs import ADDRESS, check_distinct_seeds, check_seed_folder, expected_run, run_all

__all__ = ["PAPER_TABLE", "baseline_markdown", "run_experiment", "table_markdown"]

# The QD paper's Table 3 (10 runs merged): best score, QD score and archive size, as evolved (100 ticks), on new
# seeds (100 ticks) and on new seeds with 500-tick episodes.
PAPER_TABLE = {
    "entities_nodes": [(0.941, 2235, 9986), (0.941, 2197, 9975), (0.941, 2086, 9962)],
    "entities_entropy": [(0.958, 2156, 6974), (0.958, 2005, 6951), (0.958, 2011, 6950)],
}
PASSES = ("as evolved", "new seeds", "new seeds, longer episodes")


def run_experiment(
    measures: str,
    out_dir: str | Path,
    *,
    config: str | Path,
    seeds: Sequence[int] = tuple(range(20, 30)),
    parallel: int = 2,
    threads: int = 1,
    cluster: str = "",
    generations: int | None = None,
    longer: int = 5,
    progress: bool = True,
    optimizer: str | None = None,
) -> dict[str, Any]:
    """Run (or finish) every seed's run, then write and return the table (see the module's description). With
    ``optimizer``, every run uses it instead of the configuration's (``"random"``: random search at its budget)."""
    from structgen.domains.fortress.problem import MEASURES
    from structgen.domains.fortress.robustness import open_runs, reevaluate

    if measures not in MEASURES:
        raise InputError(f"measures must be one of {', '.join(MEASURES)}, got {measures!r}")
    check_distinct_seeds(seeds)
    if not Path(config).is_file():
        raise InputError(f"{config}: no such configuration file")
    if cluster and not ADDRESS.fullmatch(cluster):
        raise InputError(f"--cluster {cluster[:60]!r}: not a Dask scheduler's address (tcp://host:port or host:port)")
    overrides = (f"problem.measures={measures}",) + ((f"optimizer.name={optimizer}",) if optimizer else ())
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: is not a folder; OUT_DIR holds the runs and the table")
    # Every seed's folder is checked before any run starts, so that nothing runs for a table that would be refused.
    for seed in seeds:
        check_seed_folder(out / f"seed-{seed}", expected_run(config, overrides, seed, generations, "fortress-v0"))
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"{out}: cannot make this folder ({err.strerror})") from None
    jobs = [(str(config), overrides, seed, str(out / f"seed-{seed}"), threads, generations) for seed in seeds]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), desc=f"{measures} runs", unit="run", file=sys.stderr)
    try:
        run_all(jobs, parallel, cluster, lambda done: bar.update(1) if bar is not None else None)
    finally:
        if bar is not None:
            bar.close()
    folders, experiment = open_runs([job[3] for job in jobs])
    report = reevaluate(folders, experiment, longer=longer, progress=progress)
    report.update({"measures": measures, "run_seeds": list(seeds), "longer": longer, "paper": PAPER_TABLE[measures]})
    report["optimizer"] = experiment.optimizer_name
    write_table(out / "table", report, table_markdown(report))
    return report


def table_markdown(report: dict[str, Any]) -> str:
    """Table 3's half for these measures: the merged archive of the runs (and the runs' spread) beside the paper's."""
    rows = report["rows"]
    merged = [row for row in rows if row["name"].startswith("merged")]
    runs = len(report["run_seeds"])
    singles = [[row for row in rows if row["name"].startswith("run ") and _pass_of(row["name"]) == p] for p in range(len(PASSES))]
    searched = " of random search" if report.get("optimizer") == "random" else ""
    header = f"| {report['measures']} ({runs} runs{searched}) | ticks | best | QD score | cells | QD score of one run (min-max) |"
    lines = [header + " paper: best / QD score / cells |", "|---|---:|---:|---:|---:|---:|---:|"]
    ticks = [report["steps"], report["steps"], report["steps"] * report["longer"]]
    for p, name in enumerate(PASSES):
        row = merged[p] if len(merged) > p else (singles[p][0] if singles[p] else None)
        if row is None:
            continue
        steps = ticks[p]
        scores = [r["qd_score"] for r in singles[p]]
        spread = f"{min(scores):,.0f}-{max(scores):,.0f}" if scores else ""
        best, qd, cells = report["paper"][p]
        lines.append(
            f"| {name} | {steps} | {row['best']:.3f} | {row['qd_score']:,.0f} | {row['cells']:,} | {spread} | "
            f"{best:.3f} / {qd:,} / {cells:,} |"
        )
    return "\n".join(lines) + "\n"


def baseline_markdown(report: dict[str, Any], baseline: dict[str, Any]) -> str:
    """MAP-Elites' runs against random search's at the same evaluations into the same cells: each pass's QD score
    of one run (over the runs) and its best fitness, with the three-standard-error verdict (:mod:`evolution.stats`)."""
    from evolution.stats import compare

    lines = [f"#### {report['measures']}: does MAP-Elites learn? Against random search at the same evaluations", ""]
    for p, name in enumerate(PASSES):
        ours, theirs = (
            [row for row in r["rows"] if row["name"].startswith("run ") and _pass_of(row["name"]) == p]
            for r in (report, baseline)
        )
        if not ours or not theirs:
            continue
        for what, key in (("QD score of one run", "qd_score"), ("best fitness of one run", "best")):
            compared = compare([row[key] for row in ours], [row[key] for row in theirs])
            lines.append(f"- {name}, {what}: " + compared.sentence("MAP-Elites", "random search") + ".")
    return "\n".join(lines) + "\n"


def _pass_of(name: str) -> int:
    if ", new seeds, " in name:
        return 2
    if ", new seeds" in name:
        return 1
    return 0
