"""The stable-structures paper's four experiments at its own settings, a table beside its numbers, and its figures.

``structgen structures experiment NAME OUT_DIR`` runs ``configs/paper_<NAME>.toml`` once per seed (default 0, 1, 2),
each in its own run folder ``OUT_DIR/seed-<S>``, several at a time (:mod:`structgen.runs.seed_runs`: a folder that exists
is resumed, or kept when it got far enough). Each run stops at the generations holding the paper's spawn numbers on
the way (``milestones``) and keeps its best structure there in ``OUT_DIR/seed-<S>-spawns/spawn-<N>/``, the pictures
the ``figure`` command lays out as the paper's figures 4 to 9. Then the table is written from the runs' metrics:
``OUT_DIR/table.json`` and ``OUT_DIR/table.md``.

Spawns count the networks evaluated: generation 1 evaluates the whole population (spawns 1 to 100), every later
generation the children (80 more), so spawn N lies in generation 1 + ceil((N - 100) / 80). The paper's "93rd
evolution iteration" is generation 94 here (its iterations count after the first population).
"""

from __future__ import annotations

import io
import math
import re
import shutil
import statistics
import sys
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from evolution.files import atomic_write, read_png, write_table
from evolution.stats import mean_and_standard_error
from structgen.errors import InputError
from structgen.runs import read_best
from structgen.runs.seed_runs import check_distinct_seeds, check_seed_folder, expected_run, run_seed

__all__ = [
    "EXPERIMENTS",
    "PAPER_TABLE_1",
    "TABLE_SPAWNS",
    "figure",
    "generation_of",
    "merge_results",
    "run_experiment",
    "seed_row",
    "table_markdown",
]


#: The domain the paper's experiments run (its configurations name it).
_DOMAIN_ID = "structures-v0"


@dataclass(frozen=True)
class PaperExperiment:
    """One of the paper's experiments: its configuration file, its spawn budget, the spawns its figures show, and
    what it reports."""

    config: str
    spawns: int
    milestones: tuple[int, ...]
    reports: str


EXPERIMENTS = {
    "baseline": PaperExperiment(
        "configs/paper_baseline.toml",
        28_577,
        (6_135, 7_480, 28_577),
        "first integrity 1 at spawn 7,480 (its 93rd iteration); the final structure (spawn 28,577) three vertices "
        "tall, its upper layer joined",
    ),
    "cutoff": PaperExperiment("configs/paper_cutoff.toml", 5_800, (381, 5_800), "four vertices tall at spawn 5,800 (cutoff 0.6)"),
    "no-build-down": PaperExperiment(
        "configs/paper_no-build-down.toml",
        6_811,
        (6_811,),
        "at spawn 6,811 a structure like the 40-hour experiment's final one, with fewer vertices",
    ),
    "average-height": PaperExperiment(
        "configs/paper_average-height.toml", 28_577, (28_577,), "a small foundation with a spike (no spawn named)"
    ),
}
#: Spawns at which every run also keeps its best and its parents, for the pictures and the judge's sample.
SAMPLE_SPAWNS = (500, 2_000, 4_000, 10_000, 20_000)
#: Spawns at which the table gives the tallest structure standing so far (the paper's figures' spawn numbers).
TABLE_SPAWNS = (5_800, 6_811, 7_480, 28_577)
#: The paper's Table 1: seconds per generation and per structure (its evaluator) by the population's mean integrity.
PAPER_TABLE_1 = {"< 0.5": (2044.41, 25.06), "0.5 to 1": (1060.41, 11.99), "= 1": (131.25, 1.42)}
_FIRST, _LATER = 100, 80


def generation_of(spawn: int, first: int = _FIRST, later: int = _LATER) -> int:
    """The generation that evaluates spawn number ``spawn`` (1-based)."""
    return 1 if spawn <= first else 1 + math.ceil((spawn - first) / later)


def spawns_by(generation: int, first: int = _FIRST, later: int = _LATER) -> int:
    """Spawns evaluated by the end of ``generation``."""
    return first + later * (generation - 1)


def _regime(mean_integrity: float) -> str:
    if mean_integrity >= 1 - 1e-9:
        return "= 1"
    return "< 0.5" if mean_integrity < 0.5 else "0.5 to 1"


#: What a table reads of each metrics row (absent ones count as 0 where the table allows it).
_ROW_NUMBERS = (
    "generation", "evaluations", "wall_s", "best_objective", "workers", "generation_mean_integrity",
    "generation_max_standing_height", "generation_max_standing_vertices", "generation_max_standing_edges",
)  # fmt: skip


def seed_row(run_dir: Path, workers: int) -> dict[str, Any]:
    """One run's line of the table, from its metrics and its best candidate."""
    from evolution import RunFolder
    from structgen.runs import check_numbers, open_run

    folder, _ = open_run(run_dir)
    rows = folder.metrics()
    if not rows:
        raise InputError(f"{run_dir}: the run has no finished generation yet")
    check_numbers(folder / RunFolder.METRICS, rows, _ROW_NUMBERS)
    first_whole = next((r for r in rows if r.get("generation_max_standing_edges", 0) > 0), None)
    tallest: dict[str, Any] = {}
    for spawn in TABLE_SPAWNS:
        upto = [r for r in rows if r["generation"] <= generation_of(spawn)]
        if rows[-1]["generation"] < generation_of(spawn):
            tallest[str(spawn)] = None  # the run did not get that far
            continue
        tallest[str(spawn)] = {
            "height": max(r["generation_max_standing_height"] for r in upto),
            # Only the screened evaluator records sizes (a run of another configuration shows 0 there).
            "vertices": max(r.get("generation_max_standing_vertices", 0.0) for r in upto),
            "edges": max(r.get("generation_max_standing_edges", 0.0) for r in upto),
        }
    regimes: dict[str, list[tuple[float, float]]] = {}
    for before, row in zip([{"wall_s": 0.0, "evaluations": 0}, *rows], rows):
        seconds = row["wall_s"] - before["wall_s"]
        structures = row["evaluations"] - before["evaluations"]
        # Rows record the processes their generation ran with (a resume may change them); older rows do not, and
        # count the ``workers`` given here. With no worker processes the run's own process evaluates: one core.
        cores = max(row.get("workers", workers), 1)
        if seconds > 0 and structures > 0:
            # Core-seconds per structure: the evaluator's cost had it run on one core, as the paper's did.
            regimes.setdefault(_regime(row["generation_mean_integrity"]), []).append((seconds, seconds * cores / structures))
    best_file = folder.path / "best" / "best.json"
    best = read_best(best_file) if best_file.is_file() else {}
    return {
        "run": run_dir.name,  # the seed's folder inside OUT_DIR: a table names no machine's paths
        "generations": rows[-1]["generation"],
        "spawns": rows[-1]["evaluations"],
        "wall_s": rows[-1]["wall_s"],
        "first_standing_with_edges_spawn": spawns_by(first_whole["generation"]) if first_whole else None,
        "first_standing_with_edges_generation": first_whole["generation"] if first_whole else None,
        "tallest_standing": tallest,
        "best_objective": rows[-1]["best_objective"],
        "best_fields": best.get("fields", {}),
        "table_1": {
            name: {
                "generations": len(pairs),
                "seconds_per_generation": statistics.fmean(p[0] for p in pairs),
                "core_seconds_per_structure": statistics.fmean(p[1] for p in pairs),
            }
            for name, pairs in regimes.items()
        },
    }


def _snapshot(run_dir: Path, spawn: int) -> None:
    """Keep the run's best candidate as it is at the end of the generation holding ``spawn``, and its parents then
    (``parents.npy``: the population a judge's agreement is measured on, generation by generation)."""
    import numpy as np

    from structgen.runs import open_run

    target = run_dir.parent / f"{run_dir.name}-spawns" / f"spawn-{spawn}"
    if target.exists():
        return
    staging = target.with_name(target.name + ".partial")
    shutil.rmtree(staging, ignore_errors=True)
    shutil.copytree(run_dir / "best", staging)
    parents = getattr(open_run(run_dir)[0].load_checkpoint().optimizer, "parents", None)
    if parents is not None:  # random search keeps no population to judge
        np.save(staging / "parents.npy", np.asarray(parents, dtype=np.float64))
    staging.rename(target)


def _run_one_seed(
    config: str,
    overrides: Sequence[str],
    seed: int,
    run_dir: str,
    workers: int,
    generations: int,
    milestones: Sequence[int],
) -> str:
    """Run a seed to each milestone generation in turn (keeping its best there), then to ``generations``."""
    from structgen.runs import open_run

    path = Path(run_dir)
    for spawn in sorted(milestones):
        stop = generation_of(spawn)
        if stop > generations:
            break
        reached = 0
        if (path / "config.toml").is_file():
            rows = open_run(path)[0].metrics()
            reached = rows[-1]["generation"] if rows else 0
        if reached > stop:
            continue  # gone past it already (an older run); its best there is not known any more
        run_seed(config, overrides, seed, run_dir, 1, stop, workers)
        _snapshot(path, spawn)
    run_seed(config, overrides, seed, run_dir, 1, generations, workers)
    return run_dir


def _run_seeds(
    name: str,
    config: str,
    overrides: Sequence[str],
    seeds: Sequence[int],
    out: Path,
    parallel: int,
    workers: int,
    generations: int,
    milestones: Sequence[int],
    progress: bool,
) -> None:
    """Every seed's run to ``generations``, ``parallel`` at a time, each in its own process."""
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(seeds), desc=f"{name} runs", unit="run", file=sys.stderr)
    try:
        with ThreadPoolExecutor(max_workers=parallel) as pool:  # threads only wait on the run processes
            jobs = [
                pool.submit(_run_one_seed, config, overrides, seed, str(out / f"seed-{seed}"), workers, generations, milestones)
                for seed in seeds
            ]
            for job in as_completed(jobs):
                job.result()
                if bar is not None:
                    bar.update(1)
    finally:
        if bar is not None:
            bar.close()


def run_experiment(
    name: str,
    out_dir: str | Path,
    *,
    config: str | Path | None = None,
    seeds: Sequence[int] = (0, 1, 2),
    parallel: int = 2,
    workers: int = 1,
    spawns: int | None = None,
    progress: bool = True,
    results: str | Path | None = None,
    table_only: bool = False,
    optimizer: str | None = None,
) -> dict[str, Any]:
    """Run (or finish) every seed's run, then write and return the table (see the module's description); with
    ``results``, also put it into the tables of all four experiments (:func:`merge_results`). With ``table_only``
    nothing runs: the table is written from the runs as they stand, an unfinished one with the spawns it reached.
    With ``optimizer``, every run uses it instead of the configuration's GA (``"random"``: random search at the
    GA's budget, 100 genomes and then 80 a generation, the baseline); its table is kept beside the GA's."""
    if name not in EXPERIMENTS:
        raise InputError(f"experiment must be one of {', '.join(EXPERIMENTS)}, got {name!r}")
    paper = EXPERIMENTS[name]
    config = str(config or paper.config)
    if not Path(config).is_file():
        raise InputError(f"{config}: no such configuration file (run from the project's folder, or pass --config)")
    budget = paper.spawns if spawns is None else spawns
    generations = generation_of(budget)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: is not a folder; OUT_DIR holds the runs and the table")
    check_distinct_seeds(seeds)
    overrides = (f"optimizer.name={optimizer}",) if optimizer else ()
    # Everything that can be refused is refused before the first run starts: the configuration's domain, every
    # seed's folder, and where the results go.
    for seed in seeds:
        run_dir = out / f"seed-{seed}"
        if table_only and not (run_dir / "metrics.jsonl").is_file():
            raise InputError(f"{run_dir}: no run here to put in the table (run it without --table-only)")
        expected = expected_run(config, overrides, seed, generations, _DOMAIN_ID)
        check_seed_folder(run_dir, expected, any_length=True)
    if out.is_dir():
        from evolution.files import check_output

        for table in ("table.json", "table.md"):  # not ``name``: that is the experiment's
            check_output(out / table)
    if results is not None:
        _results_tables(results)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"{out}: cannot make this folder ({err.strerror})") from None
    if not table_only:
        milestones = sorted(set(paper.milestones) | set(SAMPLE_SPAWNS))
        _run_seeds(name, config, overrides, seeds, out, parallel, workers, generations, milestones, progress)
    report = {
        "experiment": name,
        "config": config,
        "optimizer": optimizer,
        "seeds": list(seeds),
        "spawn_budget": budget,
        "paper_spawn_budget": paper.spawns,
        "generations": generations,
        "workers_per_run": workers,
        "paper": paper.reports,
        "paper_table_1": {k: {"seconds_per_generation": v[0], "seconds_per_structure": v[1]} for k, v in PAPER_TABLE_1.items()},
        "runs": [seed_row(out / f"seed-{seed}", workers) for seed in seeds],
    }
    write_table(out / "table", report, table_markdown(report))
    if results is not None:
        merge_results(report, results)
    return report


def merge_results(report: dict[str, Any], stem: str | Path) -> None:
    """Put one experiment's table into the tables of all four (``STEM.json``, keyed by experiment, and ``STEM.md``,
    every experiment's table in the paper's order), replacing that experiment's earlier one."""
    stem = Path(stem)
    _, tables = _results_tables(stem)
    tables[table_key(report["experiment"], report.get("optimizer"))] = report
    ordered = {key: tables[key] for name in EXPERIMENTS for key in _keys_of(name) if key in tables}
    command = f"structgen structures experiment NAME OUT_DIR --results {stem}"
    text = f"# The stable-structures paper's experiments, run here\n\nWritten by `{command}`.\n\n"
    parts = []
    for name in EXPERIMENTS:
        parts += [table_markdown(tables[key]) for key in _keys_of(name) if key in tables]
        if name in tables and (baseline := tables.get(table_key(name, "random"))) is not None:
            parts.append(baseline_markdown(tables[name], baseline))
    write_table(stem, ordered, text + "\n".join(parts))


def table_key(experiment: str, optimizer: str | None) -> str:
    """Where an experiment's table is kept among all four's: its name, or its name and the optimiser its runs used
    in place of the configuration's (``"cutoff --optimizer random"``)."""
    return experiment if not optimizer else f"{experiment} --optimizer {optimizer}"


def _keys_of(experiment: str) -> list[str]:
    from evolution.registry import OPTIMIZERS

    return [experiment, *(table_key(experiment, name) for name in OPTIMIZERS)]


def baseline_markdown(report: dict[str, Any], baseline: dict[str, Any]) -> str:
    """The GA's runs against random search's at the same spawns, seed for seed: the best score Q and the tallest
    structure standing by the end, each with the three-standard-error verdict (:mod:`evolution.stats`)."""
    from evolution.stats import compare

    name = report["experiment"]
    lines = [f"#### {name}: does the GA learn? Against random search at the same spawns and judge", ""]
    if report["spawn_budget"] != baseline["spawn_budget"]:
        return "\n".join(lines + [f"Not compared: the GA ran {report['spawn_budget']:,} spawns, random search "
                                  f"{baseline['spawn_budget']:,}.", ""])  # fmt: skip
    within = [spawn for spawn in TABLE_SPAWNS if spawn <= report["spawn_budget"]]
    measures: list[tuple[str, Any]] = [("best Q", lambda run: run["best_objective"])]
    if within:  # the tallest standing by the last of the paper's spawn numbers the runs reached

        def tallest(run: dict[str, Any]) -> float:
            found = run["tallest_standing"].get(str(within[-1]))
            return found["height"] if found else 0.0

        measures.append((f"tallest H standing by spawn {within[-1]:,}", tallest))
    for what, value in measures:
        compared = compare([value(r) for r in report["runs"]], [value(r) for r in baseline["runs"]])
        lines.append(f"- {what}: " + compared.sentence("the GA", "random search") + ".")
    return "\n".join(lines) + "\n"


def _results_tables(stem: str | Path) -> tuple[Path, dict[str, Any]]:
    """``STEM.json`` and the tables it holds (none if it is not there yet), checked as :func:`merge_results` will
    write it: both files writable, the JSON an object keyed by experiment."""
    from evolution.files import MiB, check_output, read_json

    stem = Path(stem)
    path = stem.with_name(stem.name + ".json")
    folder = stem.parent  # made if missing: then the nearest folder that is there must take it
    while not folder.exists() and not folder.is_symlink() and folder != folder.parent:
        folder = folder.parent
    for target in (path, stem.with_name(stem.name + ".md")):
        check_output(target if folder == stem.parent else folder / target.name)
    if not path.exists():
        return path, {}
    tables = read_json(path, 64 * MiB)
    known = {key for name in EXPERIMENTS for key in _keys_of(name)}
    if not isinstance(tables, dict) or not all(name in known and isinstance(table, dict) for name, table in tables.items()):
        raise InputError(
            f"{path}: not the JSON these tables are kept in (an object keyed by experiment: {', '.join(EXPERIMENTS)})"
        )
    return path, tables


def _mean_se(values: Sequence[float]) -> str:
    if not values:
        return "not reached"
    mean, error = mean_and_standard_error(values)
    return f"{mean:,.0f}" if math.isnan(error) else f"{mean:,.0f} ± {error:,.0f}"


def table_markdown(report: dict[str, Any]) -> str:
    """The experiment's table: per run and over runs, beside the paper's numbers."""
    runs = report["runs"]
    spawns = [s for s in TABLE_SPAWNS if s <= report["spawn_budget"]]
    optimizer = report.get("optimizer")
    searched = f" with --optimizer {optimizer}" if optimizer else ""
    lines = [
        f"### {table_key(report['experiment'], optimizer)}: {len(runs)} run{'s' if len(runs) != 1 else ''} of "
        f"{report['config']}{searched}, "
        f"{report['spawn_budget']:,} spawns each "
        f"(the paper: {report['paper_spawn_budget']:,}, one run)",
        "",
        f"The paper: {report['paper']}. Each cell below: the tallest structure that stood with no joint broken by "
        "that spawn (H, and in brackets how many vertices tall), then the most vertices and edges of any that stood.",
        "",
        "| seed | spawns | first standing with an edge, by spawn | "
        + "".join(f"by spawn {s:,}: H (tall) / V / E | " for s in spawns)
        + "best Q | wall time |",
        "|---|---:|---:|" + "---:|" * len(spawns) + "---:|---:|",
    ]
    for seed, run in zip(report["seeds"], runs):
        cells = []
        for spawn in spawns:
            t = run["tallest_standing"][str(spawn)]
            if t is None:
                cells.append("not reached")
                continue
            if not t["vertices"] and not t["height"]:
                cells.append("none stood")
                continue
            cells.append(f"{t['height']:.2f} ({round(t['height']) + 1}) / {t['vertices']:.0f} / {t['edges']:.0f}")
        first = run["first_standing_with_edges_spawn"]
        lines.append(
            f"| {seed} | {run['spawns']:,} | {'not reached' if first is None else f'{first:,}'} | "
            + "".join(f"{cell} | " for cell in cells)
            + f"{run['best_objective']:.2f} | {run['wall_s'] / 60:.1f} min |"
        )
    firsts = [r["first_standing_with_edges_spawn"] for r in runs if r["first_standing_with_edges_spawn"] is not None]
    reached = f"{len(firsts)} of {len(runs)} runs"
    paper_first = "; the paper's 40-hour run: 7,480" if report["experiment"] == "baseline" else ""
    lines += [
        "",
        f"First structure standing with at least one edge (integrity 1): {_mean_se(firsts)} (mean ± standard error "
        f"over the {reached} that reached one{paper_first}).",
        "",
        "The paper's Table 1 measured here (seconds per generation on this machine, core-seconds per structure):",
        "",
        "| population's mean integrity | generations | s per generation | core-s per structure | paper: s per generation "
        "/ per structure | speed-up per structure |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for regime, (paper_generation, paper_structure) in PAPER_TABLE_1.items():
        found = [r["table_1"][regime] for r in runs if regime in r["table_1"]]
        if not found:
            lines.append(f"| {regime} | 0 | | | {paper_generation:,.0f} / {paper_structure:.2f} | |")
            continue
        count = sum(f["generations"] for f in found)
        per_generation = sum(f["seconds_per_generation"] * f["generations"] for f in found) / count
        per_structure = sum(f["core_seconds_per_structure"] * f["generations"] for f in found) / count
        lines.append(
            f"| {regime} | {count} | {per_generation:.2f} | {per_structure:.3f} | {paper_generation:,.0f} / "
            f"{paper_structure:.2f} | {paper_structure / per_structure:,.0f}x |"
        )
    return "\n".join(lines) + "\n"


def figure(out_dir: str | Path, output: str | Path | None = None) -> str:
    """One PNG of the pictures an experiment kept: a row per seed, a column per spawn number. Returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    if not out.is_dir():
        raise InputError(f"{out}: no such folder (an experiment's OUT_DIR)")
    kept: dict[tuple[int, int], Path] = {}
    for picture in sorted(out.glob("seed-*-spawns/spawn-*/structure.png")):
        seed_name, spawn_name = picture.parent.parent.name, picture.parent.name
        named = re.fullmatch(r"seed-(\d{1,10})-spawns", seed_name), re.fullmatch(r"spawn-(\d{1,10})", spawn_name)
        if not all(named):
            raise InputError(f"{picture.parent}: not a folder an experiment keeps (seed-S-spawns/spawn-N, S and N numbers)")
        kept[int(named[0].group(1)), int(named[1].group(1))] = picture
    if not kept:
        raise InputError(f"{out}: no pictures kept here (an experiment keeps them in seed-S-spawns/spawn-N/)")
    seeds = sorted({seed for seed, _ in kept})
    spawns = sorted({spawn for _, spawn in kept})
    target = Path(output) if output else out / "figure.png"
    # Everything is read and checked before the figure is drawn: a damaged copy is refused, naming the file.
    panels = {}
    for place, picture in kept.items():
        best_file = picture.parent / "best.json"
        best = read_best(best_file) if best_file.is_file() else {}
        panels[place] = read_png(picture), best
    fig, axes = plt.subplots(len(seeds), len(spawns), figsize=(4 * len(spawns), 4 * len(seeds)), squeeze=False)
    for row, seed in enumerate(seeds):
        for column, spawn in enumerate(spawns):
            ax = axes[row][column]
            ax.axis("off")
            if (seed, spawn) in panels:
                image, best = panels[seed, spawn]
                ax.imshow(image)
                fields = best.get("fields", {})
                ax.set_title(
                    f"seed-{seed}, best by spawn {spawn:,}\nQ {best.get('objective', float('nan')):.1f}, I "
                    f"{fields.get('integrity', float('nan')):.2f}, H {fields.get('height', float('nan')):.1f}, "
                    f"V {fields.get('complexity', float('nan')):.0f}",
                    fontsize=9,
                )
            else:
                ax.set_title(f"seed-{seed}: not kept at spawn {spawn:,}", fontsize=9)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=64, format="png")
    plt.close(fig)
    atomic_write(target, buffer.getvalue())
    return str(target)
