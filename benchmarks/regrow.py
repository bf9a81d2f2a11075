"""Growth that repairs itself: the shipped NCAs' structures cut and grown on (`structgen regrow`), a row per NCA,
cut and damage: the share of the original's members that regrew (mean and lowest over the cuts), the members that
grew where the original had none, and how many regrown structures stand (static analysis, faithful preset).

    python benchmarks/regrow.py [--damage 0.1 0.25 0.5] [--seeds 5] [--only FILE ...] [--sweep [--transient] [--workers 2]]

A mid cut is one (the members nearest the middle height); random cuts are drawn with seeds 0 .. seeds - 1.
``--sweep`` instead counts, per NCA, the cuts regrown (at least 95 % of the members back, and standing) over every
mid cut from 1 % to 99 % of the members and ten random cuts (seeds 100 to 109) at each of 5 % to 50 % in steps of
5 %: cuts no search here was trained on. ``--transient`` also holds each of those to PyBullet's first 0.3 s of the
faithful preset (``tall.transient_peak`` at most the break force; seconds a tower, so use it with ``--only``).
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from physics import PhysicsConfig  # noqa: E402
from structgen.domains.structures.regrow import regrow  # noqa: E402
from structgen.domains.structures.tall import transient_peak  # noqa: E402
from structgen.nca import NCAConfig, grow  # noqa: E402

#: The shipped NCAs with the settings their grow commands in docs/structures.md use.
SHIPPED = {
    "taught tower, 7 levels (docs/tall_grown_7.npy)": ("tall_grown_7.npy", NCAConfig(max_extent=6, iterations=6)),
    "taught tower, 7 levels, chosen to regrow (docs/tall_regrow_7.npy)": (
        "tall_regrow_7.npy",
        NCAConfig(max_extent=6, iterations=6),
    ),
    "taught tower, 8 levels (docs/tall_grown_8.npy)": ("tall_grown_8.npy", NCAConfig(max_extent=7, iterations=7)),
    "taught tower, 8 levels, chosen to regrow (docs/tall_regrow_8.npy)": (
        "tall_regrow_8.npy",
        NCAConfig(max_extent=7, iterations=7),
    ),
    "taught tower, 9 levels (docs/tall_grown_9.npy)": ("tall_grown_9.npy", NCAConfig(max_extent=8, iterations=8)),
    "evolved five levels (docs/tall_five_levels_nca.npy)": (
        "tall_five_levels_nca.npy",
        NCAConfig(iterations=10, cutoff=0.6, build_down=False, max_vertices=200),
    ),
    "evolved large flat (docs/large_flat_nca.npy)": ("large_flat_nca.npy", NCAConfig(cutoff=0.6, build_down=False)),
}


def _holds(structure) -> bool:
    """Whether PyBullet's first 0.3 s of the faithful preset (joints unbreakable) keeps every joint within the break
    force: where towers break, and the judge the static analysis is checked against."""
    return transient_peak(structure) <= PhysicsConfig().break_force


def sweep(only: list[str] | None, transient: bool, workers: int) -> None:
    mid = [("mid", share / 100, 0) for share in range(1, 100)]
    random = [("random", share / 100, seed) for share in range(5, 55, 5) for seed in range(100, 110)]
    header = ["NCA", "members"]
    for kind, shares in (("mid", "1-99 %"), ("random", "5-50 %")):
        header += [f"{kind} cuts regrown ({shares})", "lowest restored"]
        header += ["of those, holding in PyBullet's first 0.3 s"] if transient else []
    print("| " + " | ".join(header) + " |")
    print("|---|" + "---:|" * (len(header) - 1))
    with ProcessPoolExecutor(workers) as pool:
        for label, (file, config) in SHIPPED.items():
            if only and file not in only:
                continue
            weights = np.load(ROOT / "docs" / file)
            grown = grow(weights, config)
            cells = []
            for cuts in (mid, random):
                results = [regrow(weights, grown, config, share, cut, seed) for cut, share, seed in cuts]
                regrown = [r.regrown for r in results if r.restored >= 0.95 and r.stands]
                cells += [f"{len(regrown)} of {len(cuts)}", f"{min(r.restored for r in results):.1%}"]
                if transient:
                    cells.append(f"{sum(pool.map(_holds, regrown))} of {len(regrown)}")
            print(f"| {label} | {grown.n_edges} | {' | '.join(cells)} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--damage", type=float, nargs="+", default=[0.1, 0.25, 0.5], help="shares cut (default 0.1 0.25 0.5)")
    parser.add_argument("--seeds", type=int, default=5, help="random cuts per share (default 5)")
    parser.add_argument("--only", nargs="+", metavar="FILE", help="only the shipped NCAs in these docs/ files")
    parser.add_argument("--sweep", action="store_true", help="count the cuts regrown over many shares and seeds instead")
    parser.add_argument(
        "--transient",
        action="store_true",
        help="with --sweep: hold each regrown tower to PyBullet's first 0.3 s too (seconds each)",
    )
    parser.add_argument("--workers", type=int, default=2, help="processes for --transient (default 2)")
    args = parser.parse_args()
    if args.sweep:
        sweep(args.only, args.transient, args.workers)
        return
    print("| NCA | members | cut | damage | restored (mean) | restored (lowest) | new members (mean) | regrown stand |")
    print("|---|---:|---|---:|---:|---:|---:|---:|")
    for label, (file, config) in SHIPPED.items():
        if args.only and file not in args.only:
            continue
        weights = np.load(ROOT / "docs" / file)
        grown = grow(weights, config)
        for cut, seeds in (("mid", [0]), ("random", range(args.seeds))):
            for share in args.damage:
                results = [regrow(weights, grown, config, share, cut, seed) for seed in seeds]
                restored = [r.restored for r in results]
                print(
                    f"| {label} | {grown.n_edges} | {cut} | {share:.0%} | {np.mean(restored):.1%} | {min(restored):.1%} | "
                    f"{np.mean([r.extra for r in results]):.0f} | {sum(r.stands for r in results)} of {len(results)} |"
                )


if __name__ == "__main__":
    main()
