"""Does training's judge rank layouts as the paper's planner does? The elites of a warehouse or manufacturing run,
grown, repaired as the run repaired them and simulated by the run's judge (its ``planner``, ``simulations`` and
``simulation_steps``) and again by ``pbs`` with the same seeds.

    python benchmarks/judge_ranking.py RUN_DIR [--layouts 200] [--workers 2] [--json OUT.json]
    python benchmarks/judge_ranking.py RUN_DIR --next 4 [--workers 2]

Prints the rank agreement of the two judges over the layouts, by throughput and by the objective the run maximises
(throughput + alpha x similarity): Spearman's rho and how many of each judge's ten best are the other's ten best.
The issue's bar for a cheaper judge: rho at least 0.95 and 8 of the top 10 shared over at least 200 layouts.
Layouts are the archive's elites (all of them, or ``--layouts`` drawn at random with seed 0), the layouts training
compares; each is also judged by both again with other simulation seeds, for how far luck alone moves a ranking.
With ``--next N``, the layouts of the N generations the run draws after its last checkpoint (asked of its
optimiser and told the training judge's results, as the run itself does; the run folder is only read).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from evolution.problem import Evaluation
from structgen.domains.layouts.measures import similarity as similarity_of
from structgen.domains.layouts.problem import LayoutProblem
from structgen.runs.experiment import load_experiment

_PROBLEMS: dict[str, LayoutProblem] = {}


def _problem(run: str, planner: str | None) -> LayoutProblem:
    key = f"{run}:{planner}"
    if key not in _PROBLEMS:
        problem = load_experiment(Path(run) / "config.toml").make_problem()
        settings = problem.settings if planner is None else dataclasses.replace(problem.settings, planner=planner)
        _PROBLEMS[key] = LayoutProblem(settings)
    return _PROBLEMS[key]


def _judge_both(run: str, genome: np.ndarray, seed: int) -> dict:
    trained = _problem(run, None)
    tiles = trained.grow(genome[None])[0]
    repaired = trained._repair(tiles, seed)
    _, similarity = similarity_of(tiles, repaired.tiles, trained.kind)
    row = {"similarity": similarity, "hamming": repaired.hamming}
    began = time.process_time()
    throughput, congested = trained._simulate(repaired.tiles, seed)
    row["judge"] = {"throughput": throughput, "congested": congested, "cpu_s": time.process_time() - began}
    return row | _judge_evaluated(run, repaired.tiles, seed)


def _judge_evaluated(run: str, repaired: np.ndarray, seed: int) -> dict:
    """``pbs`` on a layout training judged with ``seed``; and, for how far simulations' luck alone moves a ranking,
    both judges again with other simulation seeds."""
    judged = {}
    for name, planner, seeded in (("pbs", "pbs", seed), ("pbs_again", "pbs", seed + 1), ("judge_again", None, seed + 1)):
        began = time.process_time()
        throughput, congested = _problem(run, planner)._simulate(repaired, seeded)
        judged[name] = {"throughput": throughput, "congested": congested, "cpu_s": time.process_time() - began}
    return judged


def _next_generations(run: str, generations: int, workers: int) -> list[dict]:
    """The run's next ``generations`` batches from its checkpoint, each judged by training's judge (told to the
    optimiser, so the next batch is the run's) and by ``pbs``."""
    from evolution.runfolder import RunFolder

    trained = _problem(run, None)
    state = RunFolder(Path(run)).load_checkpoint(trained.genome_types, trained)
    optimizer = state.optimizer
    optimizer.attach(trained)
    rows = []
    with ProcessPoolExecutor(workers) as pool:
        for generation in range(state.generation + 1, state.generation + 1 + generations):
            genomes = np.asarray(optimizer.ask())
            seeds = np.random.SeedSequence(generation).generate_state(len(genomes))
            chunks = np.array_split(np.arange(len(genomes)), workers)
            parts = list(pool.map(_evaluate_part, [run] * len(chunks), [genomes[c] for c in chunks], [seeds[c] for c in chunks]))
            evaluation = Evaluation.concatenate([part for part, _ in parts])
            judge_cpu = sum(cpu for _, cpu in parts) / len(genomes)  # growth and repair included
            optimizer.tell(evaluation.objective, evaluation.measures, **evaluation.fields)
            kept = [i for i, extra in enumerate(evaluation.extras) if extra is not None]
            paper = list(pool.map(_judge_evaluated, [run] * len(kept), [evaluation.extras[i][0] for i in kept],
                                  [int(seeds[i]) for i in kept]))  # fmt: skip
            for i, judged in zip(kept, paper):
                fields = evaluation.fields
                rows.append({
                    "similarity": float(fields["similarity"][i]),
                    "hamming": float(fields["hamming"][i]),
                    "judge": {"throughput": float(fields["throughput"][i]), "congested": float(fields["congested"][i]),
                              "cpu_s": judge_cpu},
                    **judged,
                })  # fmt: skip
            print(f"generation {generation}: {len(kept)} layouts judged", flush=True)
    return rows


def _evaluate_part(run: str, genomes: np.ndarray, seeds: np.ndarray):
    began = time.process_time()
    evaluation = _problem(run, None).evaluate(genomes, seeds)
    return evaluation, time.process_time() - began


def top_shared(a: np.ndarray, b: np.ndarray, k: int = 10) -> int:
    """How many of the ``k`` largest of ``a`` are among the ``k`` largest of ``b`` (ties broken by index)."""
    first = set(np.argsort(-a, kind="stable")[:k].tolist())
    return len(first & set(np.argsort(-b, kind="stable")[:k].tolist()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", help="a warehouse or manufacturing run folder (with archive_solutions.npy)")
    parser.add_argument("--layouts", type=int, default=200, help="elites to judge (default 200; all if fewer)")
    parser.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    parser.add_argument("--next", type=int, default=0, metavar="N", help="judge the run's next N generations instead")
    parser.add_argument("--json", help="also write every layout's numbers here")
    args = parser.parse_args()
    alpha = _problem(args.run, None).settings.alpha
    judge = _problem(args.run, None).settings.planner
    if args.next:
        rows = _next_generations(args.run, args.next, args.workers)
        chosen = np.arange(len(rows))
        source = f"the next {args.next} generations of {args.run} after its checkpoint"
    else:
        genomes = np.load(Path(args.run) / "archive_solutions.npy")
        rng = np.random.default_rng(0)
        chosen = np.sort(rng.choice(len(genomes), min(args.layouts, len(genomes)), replace=False))
        with ProcessPoolExecutor(args.workers) as pool:
            rows = list(pool.map(_judge_both, [args.run] * len(chosen), genomes[chosen], chosen.tolist()))
        source = f"elites of {args.run} ({len(genomes)} in its archive)"
    table = {}
    for name in ("judge", "pbs", "pbs_again", "judge_again"):
        if name not in rows[0]:
            continue
        throughput = np.array([r[name]["throughput"] for r in rows])
        table[name] = {"throughput": throughput, "objective": throughput + alpha * np.array([r["similarity"] for r in rows])}
    print(f"{len(rows)} layouts, {source}; training's judge: {judge}")
    print()
    print("| ranked by | judges compared | Spearman rho | top 10 shared | means |")
    print("|---|---|---|---|---|")
    pairs = [("judge", "pbs", f"{judge} against pbs, same seeds")]
    if "pbs_again" in table:
        pairs += [
            ("pbs_again", "pbs", "pbs against pbs, other seeds"),
            ("judge_again", "judge", f"{judge} against {judge}, other seeds"),
        ]
    for what in ("throughput", "objective"):
        for first, second, words in pairs:
            a, b = table[first][what], table[second][what]
            rho = spearmanr(a, b).statistic
            print(f"| {what} | {words} | {rho:.3f} | {top_shared(a, b)} of 10 | {a.mean():.3f}, {b.mean():.3f} |")
    cpu = {name: np.mean([r[name]["cpu_s"] for r in rows]) for name in ("judge", "pbs")}  # the judge's: growth, repair too
    print()
    print(f"CPU seconds per layout's simulations: {judge} {cpu['judge']:.2f}, pbs {cpu['pbs']:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps({"elites": chosen.tolist(), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
