"""The tallest structures a local NCA can grow that stand: the table of ``structgen tall`` (``structgen.domains.structures.tall``), one row
per height, with the teaching times.

    python benchmarks/tall_grown.py [--levels 8] [--beam 30] [--candidates 12] [--no-refine] [--save-weights DIR] [--verdict 8]

Level-by-level designs (``structgen.domains.structures.samples.by_level_rules``) are searched from the top by static load, the best of
each height simulated for the faithful preset's first 0.3 s, the tallest refined by every change of two levels'
rules, and each height's design taught to the paper's 52-60-26 network (see ``structgen.domains.structures.tall`` for the steps).

``--verdict N`` also simulates the grown N-level structure for the faithful preset's full 30 s with breakable joints
(minutes for a few hundred vertices). ``--save-weights DIR`` writes each height's weights to
``DIR/tall_grown_<levels>.npy``; grow one with ``structgen grow --weights FILE --max-extent <levels - 1> -o out.json``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from physics import check_stability  # noqa: E402
from structgen.domains.structures.tall import TallSettings, find_tallest  # noqa: E402
from structgen.nca import save_weights  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--levels", type=int, default=8, help="tallest design to search, in vertices (default 8)")
    parser.add_argument("--beam", type=int, default=30, help="designs of each height kept for the next (default 30)")
    parser.add_argument("--candidates", type=int, default=12, help="teachable designs of each height simulated (default 12)")
    parser.add_argument("--max-vertices", type=int, default=700, help="largest design tried (default 700)")
    parser.add_argument("--workers", type=int, default=2, help="processes for the simulations (default 2)")
    parser.add_argument(
        "--refine",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="then try every change of two levels' rules of the tallest design (default on; a few minutes)",
    )
    parser.add_argument("--save-weights", metavar="DIR", help="write each height's taught weights here")
    parser.add_argument("--verdict", type=int, metavar="N", help="the faithful 30 s verdict of the grown N-level one")
    args = parser.parse_args()
    try:
        settings = TallSettings(args.levels, args.beam, args.candidates, args.max_vertices, args.refine)
    except ValueError as err:
        parser.error(str(err))
    if args.workers < 0:
        parser.error("--workers must be 0 (this process) or more")
    result = find_tallest(settings, workers=args.workers, log=print)
    physics = settings.physics
    print(f"search: {result.search_seconds:.0f} s")
    print()
    print(
        "| levels | rules, top level first | tied levels | vertices | edges | largest static load | peak in the first "
        "0.3 s | rules taught | teaching |"
    )
    print("|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for levels, design in sorted(result.designs.items()):
        taught = result.taught[levels]
        shown = [f"{f:.1f} N" if f <= physics.break_force else f"**{f:.1f} N**" for f in (design.static_load, design.peak)]
        print(
            f"| {levels} | {' '.join(design.rules)} | {design.tied} | {design.structure.n_vertices} | "
            f"{design.structure.n_edges} | {shown[0]} | {shown[1]} | {taught.n_rules} | {result.teach_seconds[levels]:.1f} s |"
        )
        if args.save_weights:
            save_weights(Path(args.save_weights) / f"tall_grown_{levels}.npy", taught.weights)
    if args.verdict:
        if args.verdict not in result.taught:
            parser.error(f"--verdict {args.verdict}: no teachable design of that height was found")
        clock = time.perf_counter()
        grown = result.taught[args.verdict].grown
        report = check_stability(grown, physics.replace(**physics.room_for(grown.n_vertices, grown.n_edges)))
        verdict = "stands, no joint broken" if report.stands else f"{len(report.broken_joints)} joints break"
        print(
            f"\nfaithful 30 s, the grown {args.verdict}-level structure: {verdict}, height {report.height:.3f} "
            f"({time.perf_counter() - clock:.0f} s)"
        )


if __name__ == "__main__":
    main()
