"""A warehouse, manufacturing or maze training run, summed up small enough to commit (the run folder itself is not):
its best generator's weights, its QD score and coverage over evaluations beside the paper's Table 4, and its
archive heatmap.

    python benchmarks/layout_run_summary.py RUN_DIR --name even [-o docs/layout_runs]

Writes into the output folder ``NAME_generator.npy`` (the best genome by training's objective, the NCA's weights:
``problem.grow(genome[None])`` regrows it), ``NAME_throughput_generator.npy`` (the result archive's elite of highest
throughput, the objective without its similarity term), ``NAME_summary.json`` (evaluations, the share of the paper's
budget, QD score and coverage per generation, the paper's values, both candidates' fields, and how many of the
archive's elites HiGHS, the patch repair and the row repair repaired) and ``NAME_qd.png`` (the
curves with the paper's end values), ``NAME_archive.png`` (the run's result archive) and ``NAME_layout.png`` (the best
layout, grown and repaired) and prints one table row. A run with no archive (the CMA-ES baseline) gets the generator, ``NAME_summary.json``
(its objective over evaluations), ``NAME_objective.png`` and ``NAME_layout.png``.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np

from evolution.files import atomic_write
from evolution.plots import figure_png, new_figure
from structgen.domains.layouts.repair import cheap_repair
from structgen.nca import save_weights
from structgen.runs import open_run

#: The paper's Table 4 (CMA-MAE + NCA, mean and standard error over its runs of 10,000 evaluations), by domain.
PAPER = {
    "warehouse-even": {"qd_score": (20366.07, 653.46), "coverage": (0.33, 0.01)},
    "warehouse-uneven": {"qd_score": (19985.23, 493.98), "coverage": (0.33, 0.01)},
    "manufacturing": {"qd_score": (6449.56, 1106.83), "coverage": (0.18, 0.02)},
    "maze": {"qd_score": (22299.00, 612.46), "coverage": (0.54, 0.01)},  # walls x agent path, no entropy
}
#: The paper's budget: 10,000 evaluations for the layout domains, 100,000 for the maze.
PAPER_EVALUATIONS = {"maze": 100_000}
LAYOUT_EVALUATIONS = 10_000


def _domain(config: str) -> str:
    if 'name = "maze-v0"' in config:
        return "maze"
    if "manufacturing" in config:
        return "manufacturing"
    return "warehouse-uneven" if "uneven = true" in config else "warehouse-even"


def repair_paths(problem, archive) -> dict[str, int]:
    """How the result archive's elites were repaired: by HiGHS (the run's own ``highs`` field), or on the cheap path
    by the patch repair or the row repair (found again by growing each elite: the cheap repairs are deterministic)."""
    highs = archive.columns["highs"] == 1
    paths = {"highs": int(highs.sum()), "patch": 0, "greedy": 0}
    cheap = np.flatnonzero(~highs)
    for start in range(0, len(cheap), 256):
        chunk = cheap[start : start + 256]
        for tiles in problem.grow(archive.genomes[chunk]):
            _, method = cheap_repair(tiles, problem.kind, shelves=problem.shelves, agents=problem.settings.agents)
            paths[method or "greedy"] += 1
    return paths


def summarise(run: Path, name: str, out: Path) -> dict:
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines() if line.strip()]
    if not rows:
        raise SystemExit(f"{run}: no generation recorded in metrics.jsonl")
    domain = _domain((run / "config.toml").read_text())
    best = json.loads((run / "best" / "best.json").read_text())
    out.mkdir(parents=True, exist_ok=True)
    genome = np.load(run / "best" / "genome.npy")
    save_weights(out / f"{name}_generator.npy", genome)
    evaluations = rows[-1]["evaluations"]
    budget = PAPER_EVALUATIONS.get(domain, LAYOUT_EVALUATIONS)
    common = {
        "run": name,
        "domain": domain,
        "evaluations": evaluations,
        "paper_evaluations": budget,
        "share_of_paper_budget": evaluations / budget,
        "best": best,
    }
    if "qd_score" not in rows[-1]:
        return summarise_single(run, name, out, rows, common)
    paper = PAPER[domain]
    folder, experiment = open_run(run)
    problem = experiment.make_problem()
    archive = folder.load_archive(problem)
    summary = {
        **common,
        "qd_score": rows[-1]["qd_score"],
        "coverage": rows[-1]["coverage"],
        "paper": {key: {"mean": m, "standard_error": e} for key, (m, e) in paper.items()},
        "curve": [{k: r[k] for k in ("generation", "evaluations", "qd_score", "coverage")} for r in rows],
    }
    if domain != "maze":  # mazes have no throughput and no repair
        richest = int(np.argmax(archive.objective))
        save_weights(out / f"{name}_throughput_generator.npy", archive.genomes[richest])
        summary["top_throughput"] = {column: float(values[richest]) for column, values in archive.columns.items()}
        summary["elite_repair_paths"] = repair_paths(problem, archive)
    atomic_write(out / f"{name}_summary.json", json.dumps(summary, indent=1) + "\n")
    figure = new_figure(figsize=(8, 5), layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True)
    x = [r["evaluations"] for r in rows]
    for ax, key, scale, label in ((top, "qd_score", 1, "QD score"), (bottom, "coverage", 100, "coverage (% of cells)")):
        ax.plot(x, [scale * r[key] for r in rows], lw=2, label="this run")
        mean, error = paper[key]
        ax.axhline(scale * mean, color="k", ls="--", lw=1, label=f"paper at {budget:,} evaluations")
        ax.axhspan(scale * (mean - error), scale * (mean + error), color="k", alpha=0.1)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    top.legend(loc="lower right", fontsize=8)
    top.set_title(f"{domain}: {evaluations:,} evaluations ({evaluations / budget:.0%} of the paper's)")
    bottom.set_xlabel("evaluations")
    atomic_write(out / f"{name}_qd.png", figure_png(figure))
    shutil.copyfile(run / "archive.png", out / f"{name}_archive.png")
    drawn = run / "best" / "layout.png"
    if drawn.is_file():
        shutil.copyfile(drawn, out / f"{name}_layout.png")
    return summary


def summarise_single(run: Path, name: str, out: Path, rows: list[dict], common: dict) -> dict:
    """A run with no archive (the CMA-ES baseline): its best generator, its objective over evaluations."""
    summary = {
        **common,
        "curve": [{k: r[k] for k in ("generation", "evaluations", "best_objective", "mean_objective") if k in r} for r in rows],
    }
    atomic_write(out / f"{name}_summary.json", json.dumps(summary, indent=1) + "\n")
    shutil.copyfile(run / "objective.png", out / f"{name}_objective.png")
    shutil.copyfile(run / "best" / "layout.png", out / f"{name}_layout.png")
    return summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path, help="the run folder")
    parser.add_argument("--name", required=True, help="a short name for the files (letters, digits, - and _)")
    parser.add_argument("-o", "--out", type=Path, default=Path("docs/layout_runs"), help="output folder")
    args = parser.parse_args()
    s = summarise(args.run, args.name, args.out)
    if "qd_score" not in s:
        print(
            f"| {s['run']} | {s['evaluations']:,} ({s['share_of_paper_budget']:.0%}) | best objective {s['best']['objective']:.3f} |"
        )
        return
    paper = s["paper"]
    print("| run | evaluations (share of the paper's) | QD score (paper) | coverage (paper) | best objective |")
    print("|---|---|---|---|---|")
    print(
        f"| {s['run']} | {s['evaluations']:,} ({s['share_of_paper_budget']:.0%}) | {s['qd_score']:,.0f} "
        f"({paper['qd_score']['mean']:,.0f}) | {s['coverage']:.3f} ({paper['coverage']['mean']:.2f}) | "
        f"{s['best']['objective']:.3f} |"
    )


if __name__ == "__main__":
    main()
