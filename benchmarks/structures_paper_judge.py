"""How well the paper experiments' judge decides as the paper's 30 s of gravity decides.

    python benchmarks/structures_paper_judge.py OUT_DIR [OUT_DIR ...] [--per-snapshot 8] [--random 10]
        [--workers 2] [--json FILE]

OUT_DIR is a ``structgen structures experiment`` folder. The sample: from every run, ``--per-snapshot`` of the
parents it kept at each spawn it stopped at (``seed-S-spawns/spawn-N/parents.npy``: the population across the
generations) and ``--random`` random networks of its settings (its first generation: for the baseline, blocks of
about a thousand vertices). Each structure is scored twice: by the run's own judge (the configuration's
``problem.evaluator``, the "screened" one for the paper's configurations) and by a reference simulation:

- up to ``--full-joints`` joints, the faithful preset itself (1/240 s steps, 50 solver iterations, 30 s);
- up to ``--settle-joints``, the faithful stepping stopped once everything has been at rest for 0.5 s (the same I and
  H as the full 30 s in ``benchmarks/physics.py``; 30 s of a structure of 1,000 joints costs about ten minutes);
- above, the fast preset (1/120 s, 20 iterations, at most 2 s), for at most ``--max-large`` structures drawn at
  random (a block of 12,000 joints costs a minute and a half even so); with ``--large-horizon`` only its first
  seconds: joints only ever break, so the integrity then bounds the integrity at the end from above.

The table counts each kind apart. References run ``--workers`` at a time; after each such chunk the scores so far
go to ``--json`` (marked ``partial`` until the end), so a stopped draw keeps what it had and ``--include`` takes it;
the same draw run again with ``--resume`` that file simulates only the references it lacks.

Prints the verdict agreement (stands / breaks), Spearman's rank correlation of Q over the whole sample (failing
structures included) and per experiment, the kinds of disagreement, and the cost of each judge. Each row counts the
structures drawn and, in brackets, the distinct ones: a kept population often holds one structure several times.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

from evolution.files import atomic_write  # noqa: E402
from physics import CheckPool  # noqa: E402
from structgen.runs import open_run  # noqa: E402


def _sample(out_dirs: list[str], per_snapshot: int, random_count: int, seed: int) -> list[dict]:
    rng = np.random.default_rng(seed)
    items = []
    for out in map(Path, out_dirs):
        runs = sorted(p for p in out.glob("seed-*") if p.is_dir() and not p.name.endswith("-spawns"))
        if not runs:
            raise SystemExit(f"{out}: no seed-S run folders here")
        for run in runs:
            _, experiment = open_run(run)
            problem = experiment.make_problem()
            for genome in problem.initial_genomes(random_count, rng):
                items.append({"problem": problem, "genome": genome, "source": f"{out.name}/{run.name}/random"})
            for snapshot in sorted((run.parent / f"{run.name}-spawns").glob("spawn-*/parents.npy")):
                parents = np.load(snapshot)
                chosen = rng.choice(len(parents), size=min(per_snapshot, len(parents)), replace=False)
                for index in chosen:
                    items.append(
                        {"problem": problem, "genome": parents[index], "source": f"{out.name}/{run.name}/{snapshot.parent.name}"}
                    )
    return items


def add_draw_options(parser: argparse.ArgumentParser) -> None:
    """The options that decide which structures a draw picks (with its OUT_DIRs): one place, so that a script
    drawing the same sample again has the same defaults."""
    parser.add_argument("--per-snapshot", type=int, default=8, help="parents drawn from each kept population")
    parser.add_argument("--random", type=int, default=10, help="random networks per run (its first generation)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the draw")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out_dirs", nargs="*", metavar="OUT_DIR", help="structgen structures experiment folders")
    add_draw_options(parser)
    parser.add_argument("--full-joints", type=int, default=300, help="up to this many joints: the full 30 s")
    parser.add_argument("--settle-joints", type=int, default=3000, help="up to this many: faithful, stopped at rest")
    parser.add_argument("--max-large", type=int, default=12, help="structures above that drawn into the sample")
    parser.add_argument("--large-horizon", type=float, help="simulate those for only this many seconds")
    parser.add_argument("--workers", type=int, default=2, help="processes for the reference simulations")
    parser.add_argument("--json", metavar="FILE", help="also write every structure's scores here")
    parser.add_argument(
        "--include", metavar="FILE", nargs="+", default=[], help="earlier --json files whose structures join the table"
    )
    parser.add_argument(
        "--resume", metavar="FILE", help="the --json file of this same draw, stopped: its references are not simulated again"
    )
    args = parser.parse_args()

    drawn = _sample(args.out_dirs, args.per_snapshot, args.random, args.seed) if args.out_dirs else []
    grown = [item["problem"].structure_of(item["genome"]) for item in drawn]
    large = [i for i, s in enumerate(grown) if 2 * s.n_edges > args.settle_joints]
    rng = np.random.default_rng(args.seed)
    dropped = set(rng.permutation(large)[args.max_large :].tolist())
    items = [item for i, item in enumerate(drawn) if i not in dropped]
    grown = [s for i, s in enumerate(grown) if i not in dropped]
    print(f"{len(items)} structures drawn ({len(dropped)} large ones left out)", file=sys.stderr)
    structures, references = [], []
    for item, structure in zip(items, grown):
        problem = item["problem"]
        started = time.process_time()
        judged = problem.judge(structure)
        item.update(
            judge_cpu=time.process_time() - started, vertices=structure.n_vertices, edges=structure.n_edges,
            judge_q=judged.score, judge_stands=judged.stands, judge_method=judged.method, judge_i=judged.integrity,
        )  # fmt: skip
        joints = 2 * structure.n_edges
        physics = problem.settings.physics
        if joints <= args.full_joints:
            item["reference"], reference = "faithful 30 s", physics.stepped_as("faithful")
        elif joints <= args.settle_joints:
            item["reference"], reference = "faithful, stopped at rest", physics.stepped_as("faithful").replace(early_stop=True)
        elif args.large_horizon:
            item["reference"] = f"fast preset, first {args.large_horizon:g} s"
            reference = physics.stepped_as("fast").replace(horizon=args.large_horizon)
        else:
            item["reference"], reference = "fast preset", physics.stepped_as("fast")
        structures.append(structure)
        references.append(reference)
    done = _resume(args.resume, items) if args.resume else 0
    # Per configuration (a check takes one), its size caps raised to the largest structure's, in chunks of
    # --workers structures: a reference costs minutes, so each chunk's results are written (--json) and reported
    # as they come, and a stopped draw keeps what it had.
    with CheckPool(args.workers) as pool:  # one set of worker processes for every chunk
        for config in sorted(set(references), key=str):
            # Smallest first, so a chunk's references cost about the same (no worker waits long on its neighbour)
            # and a draw stopped early has as many structures as its time allowed.
            positions = sorted(
                (i for i, c in enumerate(references) if c == config and "ref_q" not in items[i]),
                key=lambda i: structures[i].n_edges,
            )
            if not positions:
                continue
            room = config.room_for(
                max(structures[i].n_vertices for i in positions), max(structures[i].n_edges for i in positions)
            )
            for start in range(0, len(positions), args.workers):
                chunk = positions[start : start + args.workers]
                for i, report in zip(chunk, pool.check([structures[i] for i in chunk], config.replace(**room))):
                    items[i].update(
                        ref_q=report.score, ref_stands=report.stands, ref_i=report.integrity, ref_cpu=report.cpu_time
                    )  # fmt: skip
                done += len(chunk)
                print(f"{done} of {len(items)} references ({items[chunk[0]]['reference']})", file=sys.stderr)
                if args.json:
                    _write(args.json, [it for it in items if "ref_q" in it], partial=done < len(items))
    for earlier in args.include:
        items += json.loads(Path(earlier).read_text())["items"]

    agree = [it["judge_stands"] == it["ref_stands"] for it in items]
    rho = spearmanr([it["judge_q"] for it in items], [it["ref_q"] for it in items]).statistic
    kinds: dict[str, int] = {}
    for it in items:
        if it["judge_stands"] != it["ref_stands"]:
            key = f"judge ({it['judge_method']}) says {'stands' if it['judge_stands'] else 'breaks'}, reference says " + (
                "stands" if it["ref_stands"] else "breaks"
            )
            kinds[key] = kinds.get(key, 0) + 1
    print(
        "| sample | structures drawn (distinct) | verdicts agreeing | Spearman rho of Q | judge CPU s (mean) | reference CPU s (mean) |"
    )
    print("|---|---:|---:|---:|---:|---:|")

    def line(name: str, chosen: list[dict]) -> None:
        if not chosen:
            return
        same = sum(it["judge_stands"] == it["ref_stands"] for it in chosen)
        r = (
            spearmanr([it["judge_q"] for it in chosen], [it["ref_q"] for it in chosen]).statistic
            if len(chosen) > 2
            else float("nan")
        )
        print(
            f"| {name} | {len(chosen)} ({_distinct(chosen)}) | {same} ({100 * same / len(chosen):.1f} %) | {r:.3f} | "
            f"{statistics.fmean(it['judge_cpu'] for it in chosen):.3f} | {statistics.fmean(it['ref_cpu'] for it in chosen):.2f} |"
        )

    line("all", items)
    # Per experiment: a high rho over a sample of all sizes can hide a judge that mis-ranks one experiment's
    # populations, whose structures are all of about one size.
    for experiment in sorted({it["source"].split("/")[0] for it in items}):
        line(f"from {experiment}", [it for it in items if it["source"].split("/")[0] == experiment])
    for method in sorted({it["judge_method"] for it in items}):
        line(f"judged by {method}", [it for it in items if it["judge_method"] == method])
    for reference in sorted({it["reference"] for it in items}):
        line(f"reference: {reference}", [it for it in items if it["reference"] == reference])
    print()
    print(f"Agreement {100 * statistics.fmean(agree):.1f} % of {len(items)}; Spearman rho {rho:.3f}.")
    for key, count in sorted(kinds.items(), key=lambda kv: -kv[1]):
        print(f"- {count}: {key}")
    if args.json:
        _write(args.json, items, partial=False, agreement=statistics.fmean(agree), spearman=rho)


def _key(item: dict) -> tuple:
    """What tells a drawn structure apart: where it was drawn, its size and its judge's score."""
    return item["source"], item["vertices"], item["edges"], round(item["judge_q"], 9)


def _resume(path: str, items: list[dict]) -> int:
    """Take the references a stopped draw wrote to ``path`` for the structures drawn again; how many were taken. A
    file from another draw (a structure in it that this draw lacks) is refused."""
    try:
        earlier = json.loads(Path(path).read_text())["items"]
        found = {_key(it): it for it in earlier if "ref_q" in it}
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise SystemExit(f"{path}: not a --json file of this benchmark ({type(err).__name__}: {err})") from None
    taken = 0
    for item in items:
        if (reference := found.get(_key(item))) is not None:
            item.update({k: reference[k] for k in ("reference", "ref_q", "ref_stands", "ref_i", "ref_cpu")})
            taken += 1
    missing = set(found) - {_key(it) for it in items}
    if missing:
        raise SystemExit(
            f"{path}: {len(missing)} of its structures are not in this draw (another draw's file?), e.g. {min(missing)}"
        )
    print(f"{taken} references taken from {path}", file=sys.stderr)
    return taken


def _distinct(items: list[dict]) -> int:
    """How many different structures: a kept population often holds the same structure grown by several genomes,
    and a draw then picks it more than once (each pick counts in the table, as the population holds it)."""

    def run(item: dict) -> str:  # the same structure kept in two snapshots of a run is one structure
        return "/".join(item["source"].split("/")[:2])

    return len({(run(it), *_key(it)[1:]) for it in items})


def _write(path: str, items: list[dict], partial: bool, **summary: float) -> None:
    """The scores so far, atomically (``partial``: the draw had not finished; ``--include`` takes it as it is)."""
    keep = [{k: v for k, v in it.items() if k not in ("problem", "genome")} for it in items]
    atomic_write(Path(path), json.dumps({**summary, "partial": partial, "items": keep}, indent=1))


if __name__ == "__main__":
    main()
