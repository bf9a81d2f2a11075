"""How tall a structure can stand under the paper's model when it is designed vertex by vertex rather than grown:
a local search over lattice structures, judged first by the static analysis and then by the faithful simulation.

    python benchmarks/tall_design.py [--levels 6 7 8] [--seeds 0 1] [--steps 6000] [--polish 400] [--save DIR]

For each number of levels the search starts from ``structgen.domains.structures.samples.sparse_pyramid(levels)`` and anneals: each move
adds or removes a vertex or an edge together with its seven mirror images about the vertical axis through the top
(the symmetries of the square), so every design stays symmetric. Moves that disconnect the structure or lower its
top are refused. Two stages:

1. ``--steps`` moves per seed scored by the static analysis: the largest joint load (load factors applied) over two
   ground models, held and sliding (``physics.statics.bounding_loads``), plus a fiftieth of the
   mean of the twenty largest so that ties go to the design with less load elsewhere. Held ground alone lets the
   search lean on feet that in the simulation slide apart. The best design over ``--seeds`` goes on.
2. ``--polish`` moves scored by the faithful simulation itself: the largest force any joint carries in the first
   0.3 s with unbreakable joints, while the structure takes up its weight (a transient the static analysis does not
   see, 20 to 50 % above the static forces of these designs).

The final design is simulated with the faithful preset for 30 s with breakable joints: the verdict. Prints a
markdown table.
"""

from __future__ import annotations

import argparse
import math
import random
import sys
import time
from collections.abc import Callable
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from physics import PhysicsConfig, check_stability, check_transient  # noqa: E402
from physics.statics import bounding_loads  # noqa: E402
from structgen.domains.structures.samples import sparse_pyramid  # noqa: E402
from structgen.lattice import OFFSETS  # noqa: E402
from structgen.structure import Structure  # noqa: E402

Cell = tuple[int, int, int]
Edge = tuple[Cell, Cell]
NEIGHBOURS: list[Cell] = [tuple(int(v) for v in d) for d in OFFSETS.tolist()]  # type: ignore[misc]
# (sign of x, sign of y, swap x and y): the eight symmetries of the square.
MIRRORS = [(sx, sy, swap) for swap in (False, True) for sy in (1, -1) for sx in (1, -1)]


def images(cell: Cell) -> list[Cell]:
    """``cell`` under the eight symmetries of the square about the vertical axis x = y = 0."""
    x, y, z = cell
    return [((y if swap else x) * sx, (x if swap else y) * sy, z) for sx, sy, swap in MIRRORS]


def edge_images(a: Cell, b: Cell) -> set[Edge]:
    return {(min(p, q), max(p, q)) for p, q in zip(images(a), images(b))}


def to_structure(cells: set[Cell], edges: set[Edge]) -> Structure:
    ordered = sorted(cells)
    number = {cell: i for i, cell in enumerate(ordered)}
    return Structure(np.array(ordered), np.array([[number[a], number[b]] for a, b in sorted(edges)]).reshape(-1, 2), {})


def connected_to_the_top(cells: set[Cell], edges: set[Edge], top: int) -> Structure | None:
    """The design as a structure if it is one connected piece from the ground to ``top``, else None."""
    if not edges or max(c[2] for c in cells) != top or min(c[2] for c in cells) != 0:
        return None
    structure = to_structure(cells, edges)
    return structure if structure.n_components == 1 else None


def worst_and_rest(forces: np.ndarray) -> float:
    """The largest force plus a fiftieth of the mean of the twenty largest: lower is better."""
    largest = np.sort(forces)[::-1]
    return float(largest[0] + 0.02 * largest[:20].mean())


def static_score(structure: Structure, physics: PhysicsConfig) -> float:
    loads = bounding_loads(structure, physics)
    return math.inf if np.isnan(loads).any() else worst_and_rest(loads)


def transient_score(structure: Structure, physics: PhysicsConfig) -> float:
    report = check_transient(structure, physics, window=0.3)
    if report.exploded or report.error or report.height < structure.height - 0.5:
        return math.inf
    # The peak is the score; the forces at the end break ties between designs with the same peak.
    return report.peak_force + 0.02 * float(np.sort(report.joint_forces)[::-1][:20].mean())


def propose(cells: set[Cell], edges: set[Edge], top: int, rng: random.Random) -> tuple[set[Cell], set[Edge]] | None:
    """One symmetric move, or None when the drawn move does not apply."""
    new_cells, new_edges = set(cells), set(edges)
    anchor = rng.choice(sorted(cells))
    dx, dy, dz = rng.choice(NEIGHBOURS)
    other = (anchor[0] + dx, anchor[1] + dy, anchor[2] + dz)
    draw = rng.random()
    if draw < 0.3:  # remove an edge and its images
        a, b = rng.choice(sorted(edges))
        new_edges -= edge_images(a, b)
    elif draw < 0.5:  # join two vertices that are neighbours
        if other not in cells:
            return None
        new_edges |= edge_images(anchor, other)
    elif draw < 0.7:  # remove a vertex, its images and their edges
        if anchor[2] == top:
            return None
        gone = set(images(anchor))
        new_cells -= gone
        new_edges = {e for e in new_edges if e[0] not in gone and e[1] not in gone}
    else:  # a new vertex next to an existing one, joined to some of its neighbours
        if other in cells or not 0 <= other[2] <= top:
            return None
        around = [q for d in NEIGHBOURS if (q := (other[0] + d[0], other[1] + d[1], other[2] + d[2])) in cells]
        for q in rng.sample(around, rng.randint(1, len(around))):
            new_cells.update(images(other))
            new_edges |= edge_images(other, q)
    joined = {c for e in new_edges for c in e}
    return new_cells & joined, new_edges


def anneal(
    start: Structure, steps: int, seed: int, score: Callable[[Structure], float], temperature: float
) -> tuple[Structure, float]:
    """Anneal from ``start`` (its top vertex on the axis x = y = 0) for ``steps`` moves; the best design and score."""
    points = [tuple(int(v) for v in p) for p in start.vertices.tolist()]
    cells = set(points)
    edges = {(min(points[a], points[b]), max(points[a], points[b])) for a, b in start.edges.tolist()}
    top = max(c[2] for c in cells)
    rng = random.Random(seed)
    current = score(start)
    best = (current, cells, edges)
    for step in range(steps):
        move = propose(cells, edges, top, rng)
        if move is None:
            continue
        structure = connected_to_the_top(*move, top)
        trial = math.inf if structure is None else score(structure)
        # The temperature falls linearly, so late moves hardly ever make the design worse.
        heat = temperature * (1 - step / steps) + 0.01
        if trial <= current or rng.random() < math.exp(-(trial - current) / heat):
            (cells, edges), current = move, trial
            if current < best[0]:
                best = (current, cells, edges)
    return to_structure(best[1], best[2]), best[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--levels", type=int, nargs="+", default=[6, 7, 8], help="heights to design for, in vertices")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="seeds of the static stage (default 0 1)")
    parser.add_argument("--steps", type=int, default=6000, help="static-stage moves per seed (default 6000)")
    parser.add_argument("--polish", type=int, default=400, help="simulated-stage moves (default 400)")
    parser.add_argument("--save", metavar="DIR", help="write each design to DIR/design_<levels>.json")
    args = parser.parse_args()
    if any(n < 2 for n in args.levels) or args.steps < 0 or args.polish < 0:
        parser.error("--levels must be at least 2, --steps and --polish at least 0")
    physics = PhysicsConfig()
    print(f"joints break above {physics.break_force:g} N; static loads with the load factors, the larger of held and")
    print("sliding ground; peak: the largest joint force in the first 0.3 s of the faithful simulation")
    print()
    print(
        "| levels | start: static load | static stage: vertices, edges, load, peak | "
        "after polishing: vertices, edges, load, peak | time | faithful verdict (30 s) |"
    )
    print("|---:|---:|---|---|---:|---|")
    for levels in args.levels:
        start = sparse_pyramid(levels)
        begun = time.perf_counter()
        designs = [anneal(start, args.steps, seed, lambda s: static_score(s, physics), 0.3) for seed in args.seeds]
        static_best = min(designs, key=lambda pair: pair[1])[0]
        polished, _ = anneal(static_best, args.polish, 0, lambda s: transient_score(s, physics), 0.2)
        spent = time.perf_counter() - begun
        verdict = check_stability(polished, physics)
        cells = [
            f"{d.n_vertices}, {d.n_edges}, {np.nanmax(bounding_loads(d, physics)):.1f} N, {check_transient(d, physics, window=0.3).peak_force:.1f} N"
            for d in (static_best, polished)
        ]
        print(
            f"| {levels} | {np.nanmax(bounding_loads(start, physics)):.1f} N | {cells[0]} | {cells[1]} | {spent / 60:.1f} min | "
            f"{verdict.verdict()}, height {verdict.height:.2f} |",
            flush=True,
        )
        if args.save:
            Path(args.save).mkdir(parents=True, exist_ok=True)
            polished.save(Path(args.save) / f"design_{levels}.json")


if __name__ == "__main__":
    main()
