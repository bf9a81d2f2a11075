"""The tallest tower an NCA can grow that holds, for each square footprint: `structgen tall --footprint F` per side,
then why the next level fails.

    python benchmarks/tall_footprints.py --run-root DIR [--footprints 5 9 15 21 25] [--levels 9] [--workers 2]
        [--also TOWER.json ...] [--figure docs/tall_footprints.png]

Each footprint's search is a tall search folder under ``DIR`` (``f<side>``), so an interrupted run goes on where it
stopped and a finished one is only read. A footprint so wide that no design of ``--levels`` can reach its edge (a
design spreads at most one cell a level from its top vertex, so ``2 * (levels - 1) + 1`` cells hold them all) is the
unlimited search, run once (``unlimited``) and named for each such side.

Prints a markdown table: per footprint, the tallest design that holds in the faithful preset's first 0.3 s (the
transient, where tall towers break), its size and peak force, and for the next height the best design the search
found with its peak, its largest static load, and the load on its lowest joints (those at the ground level) against
the 52.5 N limit. ``--also`` adds towers found otherwise (structure files, e.g. grown from ``docs/tall_grown_9.npy``):
each counts for the footprints it fits in when it holds in the first 0.3 s (simulated in the order growth lists it).
With ``--figure``, the tallest that holds against the footprint, the next height's peak beside it.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from physics import PhysicsConfig  # noqa: E402
from physics.statics import bounding_loads  # noqa: E402
from structgen.domains.structures.tall import TallResult, TallSettings, find_tallest, transient_peak  # noqa: E402
from structgen.structure import Structure  # noqa: E402

FOOTPRINTS = (5, 9, 15, 21, 25)


def lowest_joint_load(design, physics: PhysicsConfig) -> float:
    """The largest static load (load factors applied) on a joint of a member that reaches the ground level."""
    structure = design.structure
    loads = bounding_loads(structure, physics).reshape(-1, 2)
    z = structure.vertices[:, 2]
    on_ground = (z[structure.edges[:, 0]] == 0) | (z[structure.edges[:, 1]] == 0)
    return float(np.nanmax(loads[on_ground])) if on_ground.any() else float("nan")


def search(root: Path, footprint: int, levels: int, workers: int) -> tuple[str, TallResult, float]:
    unbound = footprint >= 2 * (levels - 1) + 1
    name = "unlimited" if unbound else f"f{footprint}"
    settings = TallSettings(levels=levels, footprint=0 if unbound else footprint)
    started = time.perf_counter()
    result = find_tallest(settings, root / name, workers=workers, progress=sys.stderr.isatty())
    return name, result, time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--run-root", type=Path, required=True, help="folder for the searches' run folders")
    parser.add_argument("--footprints", type=int, nargs="+", default=list(FOOTPRINTS), help="odd sides, in cells")
    parser.add_argument("--levels", type=int, default=9, help="tallest design each search looks for (default 9)")
    parser.add_argument("--workers", type=int, default=2, help="processes for the simulations (default 2)")
    parser.add_argument("--also", type=Path, nargs="*", default=[], help="towers found otherwise (structure files)")
    parser.add_argument("--figure", type=Path, help="write the height-against-footprint picture here")
    args = parser.parse_args()
    if any(side < 1 or side % 2 == 0 for side in args.footprints):
        parser.error(f"--footprints must be odd sides of at least 1 cell, got {args.footprints}")
    physics = PhysicsConfig()
    others = []
    for path in args.also:
        tower = Structure.load(path)
        side = 2 * int(np.abs(tower.vertices[:, :2] - tower.vertices[np.argmax(tower.vertices[:, 2]), :2]).max()) + 1
        peak = transient_peak(tower, physics)
        others.append((path.name, side, int(tower.height) + 1, tower, peak))
        print(f"{path}: {int(tower.height) + 1} levels in {side}x{side}, peak {peak:.1f} N in 0.3 s", file=sys.stderr)
    rows, points = [], []
    for footprint in args.footprints:
        name, result, seconds = search(args.run_root, footprint, args.levels, args.workers)
        holding = result.tallest_holding
        best = result.designs[holding] if holding else None
        taller = result.designs.get((holding or 1) + 1)
        row = [f"{footprint}x{footprint}", name]
        fitting = [o for o in others if o[1] <= footprint and o[4] <= physics.break_force and o[2] > (holding or 0)]
        if fitting:
            label, _, levels, tower, peak = max(fitting, key=lambda o: o[2])
            row += [f"{levels} ({label})", f"{tower.n_vertices} / {tower.n_edges}", f"{peak:.1f} N", label]
            holding, taller = levels, result.designs.get(levels + 1)
        elif best is None:
            row += ["none", "", "", ""]
        else:
            size = best.structure
            row += [str(holding), f"{size.n_vertices} / {size.n_edges}", f"{best.peak:.1f} N", f"tall_{holding}.npy"]
        if taller is None:
            row += ["not searched by structgen tall", "", "", ""]
        else:
            row += [
                str(taller.levels),
                f"{taller.peak:.1f} N",
                f"{taller.static_load:.1f} N",
                f"{lowest_joint_load(taller, physics):.1f} N",
            ]
        rows.append(row + [f"{seconds:.0f} s"])
        points.append((footprint, holding or 0, taller.peak if taller else float("nan")))
    print(
        "| footprint | search folder | tallest that holds, levels | vertices / edges | its peak in 0.3 s | weights | "
        "next height | its best peak | its largest static load | static load at its lowest joints | time |"
    )
    print("|---|---|---:|---:|---:|---|---:|---:|---:|---:|---:|")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    print(f"\njoints break above {physics.break_force:g} N; search folders under {args.run_root}")
    if args.figure:
        draw(points, args.figure, physics.break_force)


def draw(points: list[tuple[int, int, float]], path: Path, break_force: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sides = [p[0] for p in points]
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.6))
    left.bar([str(s) for s in sides], [p[1] for p in points], color="#3b7dd8")
    left.set_xlabel("footprint side, cells")
    left.set_ylabel("levels")
    left.set_title("tallest an NCA grows that holds")
    for x, (_, levels, _) in enumerate(points):
        left.text(x, levels + 0.1, str(levels), ha="center")
    left.set_ylim(0, max(p[1] for p in points) + 1.5)
    right.bar(range(len(sides)), [p[2] if np.isfinite(p[2]) else 0 for p in points], color="#d8623b")
    right.set_xticks(range(len(sides)), [str(s) for s in sides])
    for x, (_, _, taller_peak) in enumerate(points):
        if not np.isfinite(taller_peak):
            right.text(x, 2, "not\nsearched", ha="center", fontsize=8)
    right.axhline(break_force, color="black", linestyle="--", linewidth=1, label=f"break force {break_force:g} N")
    right.set_xlabel("footprint side, cells")
    right.set_ylabel("peak joint force in 0.3 s, N")
    right.set_title("one level taller: its best design")
    right.legend(loc="upper right", fontsize=8)
    right.set_ylim(0, max([break_force, *[p[2] for p in points if np.isfinite(p[2])]]) * 1.25)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
