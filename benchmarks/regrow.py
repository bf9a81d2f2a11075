"""Growth that repairs itself: the shipped NCAs' structures cut and grown on (`structgen regrow`), a row per NCA,
cut and damage: the share of the original's members that regrew (mean and lowest over the cuts), the members that
grew where the original had none, and how many regrown structures stand (static analysis, faithful preset).

    python benchmarks/regrow.py [--damage 0.1 0.25 0.5] [--seeds 5]

A mid cut is one (the members nearest the middle height); random cuts are drawn with seeds 0 .. seeds - 1.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from structgen.domains.structures.regrow import regrow  # noqa: E402
from structgen.nca import NCAConfig, grow  # noqa: E402

#: The shipped NCAs with the settings their grow commands in docs/structures.md use.
SHIPPED = {
    "taught tower, 7 levels (docs/tall_grown_7.npy)": ("tall_grown_7.npy", NCAConfig(max_extent=6, iterations=6)),
    "taught tower, 8 levels (docs/tall_grown_8.npy)": ("tall_grown_8.npy", NCAConfig(max_extent=7, iterations=7)),
    "taught tower, 9 levels (docs/tall_grown_9.npy)": ("tall_grown_9.npy", NCAConfig(max_extent=8, iterations=8)),
    "evolved five levels (docs/tall_five_levels_nca.npy)": (
        "tall_five_levels_nca.npy",
        NCAConfig(iterations=10, cutoff=0.6, build_down=False, max_vertices=200),
    ),
    "evolved large flat (docs/large_flat_nca.npy)": ("large_flat_nca.npy", NCAConfig(cutoff=0.6, build_down=False)),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--damage", type=float, nargs="+", default=[0.1, 0.25, 0.5], help="shares cut (default 0.1 0.25 0.5)")
    parser.add_argument("--seeds", type=int, default=5, help="random cuts per share (default 5)")
    parser.add_argument("--only", nargs="+", metavar="FILE", help="only the shipped NCAs in these docs/ files")
    args = parser.parse_args()
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
