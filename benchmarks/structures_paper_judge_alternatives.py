"""Other judges against the same faithful references: which simulation would rank a draw's structures as the
faithful preset does, and at what cost.

    python benchmarks/structures_paper_judge_alternatives.py DRAW.json OUT_DIR [OUT_DIR ...] --per-snapshot 12
        --random 3 --seed 4 [--limit 40] [--workers 2] [--alternative horizon=1 ...]

DRAW.json is a ``structures_paper_judge.py --json`` file; OUT_DIR, ``--per-snapshot``, ``--random`` and ``--seed``
must be the ones it was drawn with, so that the same structures are drawn again (the draw is seeded). Of the
structures it has references for, the ``--limit`` smallest judged against the faithful stepping (stopped at rest or
the full 30 s) are simulated again with the fast preset, as it is and with each ``--alternative`` (comma-separated
physics settings applied to it, e.g. ``horizon=0.5`` or ``timestep=0.016667,solver_iterations=10``). Prints, for
the static analysis (the draw's own judge, where it judged) and each alternative, the verdict agreement, Spearman's
rho of Q against the reference, the mean absolute difference of integrity, and the CPU seconds a structure.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.append(str(Path(__file__).resolve().parent))  # the judge benchmark's draw, shared rather than copied

from scipy.stats import spearmanr  # noqa: E402
from structures_paper_judge import _key, _sample, add_draw_options  # noqa: E402

from physics import CheckPool  # noqa: E402
from structgen.config import parse_assignment  # noqa: E402


def _alternative(text: str) -> dict:
    changes = {}
    for assignment in filter(None, text.split(",")):
        key, value = parse_assignment(assignment)
        changes[key] = value
    return changes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("draw", metavar="DRAW.json", help="a structures_paper_judge.py --json file")
    parser.add_argument("out_dirs", nargs="+", metavar="OUT_DIR", help="the experiment folders it was drawn from")
    add_draw_options(parser)  # as the draw was made
    parser.add_argument("--limit", type=int, default=40, help="structures simulated again, smallest first")
    parser.add_argument("--workers", type=int, default=2, help="processes for the simulations")
    parser.add_argument(
        "--alternative", action="append", default=[], metavar="KEY=VALUE,...", help="fast preset with these settings"
    )
    args = parser.parse_args()

    references = {}
    for item in json.loads(Path(args.draw).read_text())["items"]:
        if item["reference"].startswith("faithful"):
            references.setdefault(_key(item), item)
    sizes = {key[:3] for key in references}
    drawn = _sample(args.out_dirs, args.per_snapshot, args.random, args.seed)
    chosen, seen = [], set()
    for item in drawn:
        structure = item["problem"].structure_of(item["genome"])
        if (item["source"], structure.n_vertices, structure.n_edges) not in sizes:
            continue  # no reference of this size: not worth the judge's second or so to find its score
        judged = item["problem"].judge(structure)
        key = _key(
            {"source": item["source"], "vertices": structure.n_vertices, "edges": structure.n_edges, "judge_q": judged.score}
        )
        if key in references and key not in seen:  # each distinct structure once
            seen.add(key)
            chosen.append((structure, references[key], item["problem"].settings.physics))
    chosen.sort(key=lambda c: c[0].n_edges)
    chosen = chosen[: args.limit]
    if not chosen:
        raise SystemExit(f"{args.draw}: none of its structures drawn again: check OUT_DIR, --per-snapshot, --random, --seed")
    print(f"{len(chosen)} structures, {chosen[0][0].n_vertices} to {chosen[-1][0].n_vertices} vertices", file=sys.stderr)

    rows = [
        ("the draw's own judge", [(c[1]["judge_stands"], c[1]["judge_q"], c[1]["judge_i"], c[1]["judge_cpu"]) for c in chosen])
    ]
    physics = chosen[0][2]
    with CheckPool(args.workers) as pool:
        for text in ["", *args.alternative]:
            config = physics.stepped_as("fast").replace(**_alternative(text))
            config = config.replace(**config.room_for(max(c[0].n_vertices for c in chosen), max(c[0].n_edges for c in chosen)))
            reports = pool.check([c[0] for c in chosen], config)
            rows.append((f"fast preset {text}".strip(), [(r.stands, r.score, r.integrity, r.cpu_time) for r in reports]))
            print(f"done: fast preset {text}", file=sys.stderr)

    reference = [(c[1]["ref_stands"], c[1]["ref_q"], c[1]["ref_i"]) for c in chosen]
    print("| judge | structures | verdicts agreeing | Spearman rho of Q | mean abs dI | CPU s per structure |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, scores in rows:
        same = sum(s[0] == r[0] for s, r in zip(scores, reference))
        rho = spearmanr([s[1] for s in scores], [r[1] for r in reference]).statistic
        d_i = statistics.fmean(abs(s[2] - r[2]) for s, r in zip(scores, reference))
        cpu = statistics.fmean(s[3] for s in scores)
        print(f"| {name} | {len(scores)} | {same} | {rho:.3f} | {d_i:.3f} | {cpu:.2f} |")


if __name__ == "__main__":
    main()
