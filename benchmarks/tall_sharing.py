"""How evenly the tallest towers share their load, and how tall that lets anything stand: the evidence behind the
twelve levels that are not reached.

    python benchmarks/tall_sharing.py [--window 0.1] [--sharing 1 1.25 1.5 1.75 2] [--steady 2 [--radii 0.1 0.3 1]]

Part one grows the towers that ship in docs/ (the grow commands of docs/structures.md) and, for each pair of
neighbouring levels, compares the largest force on the lower joints of the members between them with the even share
(:func:`structgen.domains.structures.stress.level_shares`: what each would carry were they all loaded alike along
their axes; everything above them stands on those joints). It does so for the static analysis of the intact tower
and for the largest force each joint carries in the first ``--window`` seconds of the faithful preset (joints
unbreakable, the bodies in the order growth lists them), where these towers carry most. The ratio of peak to even
share is what a design's uneven sharing costs, the spawn transient included.

``--steady SECONDS`` also runs each tower that long (joints unbreakable, no early stop) and compares the forces of
the last step, where the structure is nearly at rest, with the static analysis joint by joint, for each beam radius
of ``--radii`` (``statics_beam_radius``, whose ratio of bending to axial stiffness decides how the analysis shares
a redundant frame's load): the correlation, the largest miss, and the worst ratio at each tower's foot.

Part two is the other side: the most levels any structure of a square footprint could stand if every cut's most
loaded member carried ``sharing`` times the even share and no more (:func:`.design.tallest_possible` with
``axial=True``, the fewest bodies above each cut, judged by the break force itself as PyBullet judges), and the
bound without the axial assumption. A tower's height can be held against the model at its own ratio.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from physics import PhysicsConfig, check_stability, check_transient  # noqa: E402
from physics.statics import joint_forces  # noqa: E402
from structgen.domains.structures.design import tallest_possible  # noqa: E402
from structgen.domains.structures.stress import level_shares  # noqa: E402
from structgen.nca import NCAConfig, grow, load_weights  # noqa: E402
from structgen.structure import Structure  # noqa: E402

DOCS = Path(__file__).resolve().parents[1] / "docs"
#: The shipped towers with the growth settings of their grow commands in docs/structures.md.
TOWERS = {
    "5x5, 6 levels": ("tall_footprint_5.npy", NCAConfig(max_extent=5, iterations=6)),
    "9x9, 8 levels": ("tall_footprint_9.npy", NCAConfig(max_extent=7, iterations=7)),
    "eight (11x11)": ("tall_grown_8.npy", NCAConfig(max_extent=7, iterations=7)),
    "nine (13x13)": ("tall_grown_9.npy", NCAConfig(max_extent=8, iterations=8)),
}
FOOTPRINTS = (5, 9, 13, 15, 21, 25)


def grown() -> dict[str, Structure]:
    """The shipped towers, listed in growth order (the order PyBullet's solver visits their bodies in)."""
    return {name: grow(load_weights(DOCS / file, config), config).in_growth_order() for name, (file, config) in TOWERS.items()}


def towers(structures: dict[str, Structure], window: float, physics: PhysicsConfig) -> list[tuple[str, int, int, float]]:
    """Prints part one's table; returns each tower's name, footprint side, levels and worst simulated ratio."""
    print(f"| tower | levels | members | bodies above | even share | static peak | ratio | first {window:g} s peak | ratio |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    measured = []
    for name, structure in structures.items():
        started = time.perf_counter()
        room = physics.replace(**physics.room_for(structure.n_vertices, structure.n_edges))
        simulated = level_shares(structure, check_transient(structure, room, window=window).peak_forces, physics)
        static = level_shares(structure, joint_forces(structure, physics), physics)
        for still, moving in zip(static, simulated):
            print(
                f"| {name} | {still.level} to {still.level + 1} | {still.members:,} | {still.bodies_above:,} | "
                f"{still.even:.1f} N | {still.peak:.1f} N | {still.ratio:.2f} | {moving.peak:.1f} N | {moving.ratio:.2f} |"
            )
        side = int(np.ptp(structure.vertices[:, :2], axis=0).max()) + 1
        worst = max(row.ratio for row in simulated)
        measured.append((name, side, structure.height + 1, worst))
        print(f"{name}: {structure.n_vertices} vertices, {structure.n_edges:,} edges, judged in "
              f"{time.perf_counter() - started:.0f} s", file=sys.stderr)  # fmt: skip
    return measured


def steady(structures: dict[str, Structure], seconds: float, radii: list[float], physics: PhysicsConfig) -> None:
    """The forces of each tower nearly at rest after ``seconds``, against the static analysis at each beam radius."""
    print(f"| tower | forces after {seconds:g} s: worst ratio at the foot | beam radius | static analysis: worst ratio at "
          "the foot | correlation, joint by joint | largest miss |")  # fmt: skip
    print("|---|---:|---:|---:|---:|---:|")
    for name, structure in structures.items():
        held = physics.replace(**physics.room_for(structure.n_vertices, structure.n_edges), break_force=np.inf,
                               horizon=seconds, early_stop=False)  # fmt: skip
        resting = check_stability(structure, held).joint_forces
        foot = level_shares(structure, resting, physics)[0].ratio
        for radius in radii:
            static = joint_forces(structure, physics.replace(statics_beam_radius=radius))
            correlation = np.corrcoef(static, resting)[0, 1]
            static_foot = level_shares(structure, static, physics)[0].ratio
            print(f"| {name} | {foot:.2f} | {radius:g} m | {static_foot:.2f} | {correlation:.3f} | "
                  f"{np.abs(static - resting).max():.1f} N |")  # fmt: skip


def model(sharing: list[float], physics: PhysicsConfig) -> None:
    print("| most levels on a square footprint of side | " + " | ".join(str(f) for f in FOOTPRINTS) + " |")
    print("|---" + "|---:" * len(FOOTPRINTS) + "|")
    print("| any structure (equilibrium alone, every member loaded alike) | "
          + " | ".join(str(tallest_possible(f, f, physics)) for f in FOOTPRINTS) + " |")  # fmt: skip
    for ratio in sharing:
        heights = [tallest_possible(f, f, physics, axial=True, sharing=ratio) for f in FOOTPRINTS]
        print(f"| members loaded along their axes, peak {ratio:g} x the even share | " + " | ".join(map(str, heights)) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--window", type=float, default=0.1, help="seconds of the faithful preset simulated (default 0.1)")
    parser.add_argument("--sharing", type=float, nargs="+", default=[1.0, 1.25, 1.5, 1.75, 2.0],
                        help="peak-over-even ratios of the model's table (default 1 1.25 1.5 1.75 2)")  # fmt: skip
    parser.add_argument("--no-towers", action="store_true", help="print only the model's table")
    parser.add_argument(
        "--steady",
        type=float,
        metavar="SECONDS",
        help="also run each tower this long and hold its resting forces against the static analysis",
    )
    parser.add_argument(
        "--radii",
        type=float,
        nargs="+",
        default=[0.1, 0.2, 0.3, 0.5, 1.0, 2.0],
        help="beam radii (m) of the static analysis held against the resting forces (default 0.1 0.2 "
        "0.3 0.5 1 2; the fitted default is 0.3)",
    )
    args = parser.parse_args()
    if args.window <= 0 or any(ratio < 1 for ratio in args.sharing):
        parser.error("--window must be positive and every --sharing at least 1")
    if (args.steady is not None and args.steady <= 0) or any(radius <= 0 for radius in args.radii):
        parser.error("--steady and every --radii must be positive")
    # Judged as PyBullet judges: a joint breaks past the break force itself, no load factor.
    physics = PhysicsConfig().replace(statics_load_factor=1.0)
    structures = {} if args.no_towers and args.steady is None else grown()
    measured = [] if args.no_towers else towers(structures, args.window, physics)
    print()
    model(args.sharing, physics)
    if measured:
        print()
        print("| tower | footprint | levels | worst simulated ratio | the model's most levels at that ratio |")
        print("|---|---|---:|---:|---:|")
        for name, side, levels, worst in measured:
            allowed = tallest_possible(side, side, physics, axial=True, sharing=worst)
            print(f"| {name} | {side}x{side} | {levels} | {worst:.2f} | {allowed} |")
    if args.steady is not None:
        print()
        steady(structures, args.steady, args.radii, physics)


if __name__ == "__main__":
    main()
