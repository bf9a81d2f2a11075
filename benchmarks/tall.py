"""The tallest structure a run found that really stands: its archive's elites (or its best candidate) by height,
re-checked with PyBullet's faithful preset until one stands with no joint broken.

    python benchmarks/tall.py RUN_DIR [RUN_DIR ...] [--candidates 10] [--save-best tall.json]
    python benchmarks/tall.py --blocks
    python benchmarks/tall.py --rules

Prints a markdown table, one row per run: optimiser, evaluator, generations and run time, and the tallest elite that
the faithful simulation confirms (vertices tall = height + 1), with how many taller ones it broke.

``--blocks`` prints why dense growth cannot be tall under the paper's model: the largest joint force the static
analysis finds in solid blocks (every lattice cell a vertex) of a given width and number of levels, with every
neighbour joined or with edges along the axes only.

``--rules`` does the same for the shapes a uniform local rule grows most easily: from a single top vertex, every
vertex of a level reaches down along the same choice of neighbours (straight down, the four side diagonals, the four
corner diagonals, outwards away from the axis), optionally with ties between neighbours on the lowest levels. A beam
search from the top down (the best ``--beam`` designs of each height go on to the next) finds the rule of each
height with the smallest largest static joint load (load factors applied, the larger of held and sliding ground, as
``benchmarks/tall_design.py`` judges), and gives that design's largest joint force in the first 0.3 s of the faithful
simulation with joints that cannot break (``physics.check_transient``), where tall structures carry most.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from evolution import RunFolderError  # noqa: E402
from physics import InputError, PhysicsConfig, check_stability, joint_forces  # noqa: E402
from structgen.domains.structures.samples import by_level_rules_one_taller  # noqa: E402
from structgen.domains.structures.tall import largest_static_load, transient_peak  # noqa: E402
from structgen.lattice import OFFSETS  # noqa: E402
from structgen.runs import load_run  # noqa: E402
from structgen.structure import Structure  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="*", metavar="RUN_DIR")
    parser.add_argument("--blocks", action="store_true", help="the solid-block table instead of runs")
    parser.add_argument("--rules", action="store_true", help="the level-rule table instead of runs")
    parser.add_argument("--beam", type=int, default=10, help="--rules: designs kept per height (default 10)")
    parser.add_argument("--max-vertices", type=int, default=500, help="--rules: largest design tried (default 500)")
    parser.add_argument("--candidates", type=int, default=10, help="elites to try per run, tallest first (default 10)")
    parser.add_argument("--save-best", metavar="FILE.json", help="save the tallest confirmed structure of all runs")
    args = parser.parse_args()
    if args.blocks:
        print_blocks()
        return
    if args.rules:
        if args.beam < 1 or args.max_vertices < 1:
            parser.error("--beam and --max-vertices must be at least 1")
        print_rules(beam=args.beam, max_vertices=args.max_vertices)
        return
    if not args.runs:
        parser.error("give RUN_DIR, --blocks or --rules")
    print(
        "| run | optimizer | evaluator | generations | run time | tallest confirmed standing | vertices | taller ones that broke |"
    )
    print("|---|---|---|---:|---:|---:|---:|---:|")
    tallest = (-1.0, None)
    for run_dir in args.runs:
        with load_run(run_dir) as run:
            rows = run.metrics()
            settings = run.experiment.problem_settings
            try:
                archive = run.archive()
                order = np.argsort(-archive.columns["height"], kind="stable")
                intact = archive.columns["integrity"][order] == 1
                genomes = [archive.genomes[i] for i in order[intact][: args.candidates]]
            except RunFolderError:  # no archive: the best candidate alone
                genomes = [run.best_genome()]
            faithful = settings.physics.stepped_as("faithful")
            found, broke = None, 0
            for genome in genomes:
                structure = run.problem.structure_of(genome)
                try:
                    report = check_stability(structure, faithful)
                except InputError:
                    continue
                if report.stands:
                    found = (report.height, structure)
                    break
                broke += 1
        height = f"{found[0]:.2f} ({round(found[0]) + 1} tall)" if found else "none"
        vertices = found[1].n_vertices if found else "-"
        print(
            f"| {Path(run_dir).name} | {run.experiment.optimizer_name} | {settings.evaluator} | {rows[-1]['generation']} | "
            f"{rows[-1]['wall_s'] / 60:.1f} min | {height} | {vertices} | {broke} |",
            flush=True,
        )
        if found and found[0] > tallest[0]:
            tallest = found
    if args.save_best and tallest[1] is not None:
        print(f"\n{tallest[1].save(args.save_best)}: {tallest[1].n_vertices} vertices, height {tallest[0]:.2f}")


def solid_block(width: int | None, levels: int, offsets: np.ndarray) -> Structure:
    """Every cell of a ``width`` x ``width`` x ``levels`` box a vertex, joined to its neighbours along ``offsets``;
    width None: a solid pyramid instead, each level one cell narrower on every side than the one below."""
    if width is None:
        cells = np.array(
            [
                (x, y, z)
                for z in range(levels)
                for x in range(z - levels + 1, levels - z)
                for y in range(z - levels + 1, levels - z)
            ]
        )
    else:
        cells = np.array([(x, y, z) for x in range(width) for y in range(width) for z in range(levels)])
    index = {tuple(c): i for i, c in enumerate(cells.tolist())}
    edges = [
        (i, index[q])
        for c, i in index.items()
        for d in offsets.tolist()
        if (q := (c[0] + d[0], c[1] + d[1], c[2] + d[2])) in index and index[q] > i
    ]
    return Structure(cells, np.array(edges, dtype=np.int64).reshape(-1, 2), {})


def print_blocks(widths: tuple[int | None, ...] = (1, 2, 3, 5, None), levels: range = range(2, 9)) -> None:
    physics = PhysicsConfig()
    print(f"largest joint force (N) in a solid block, static analysis; joints break above {physics.break_force:g} N")
    print()
    print("| edges | width (pyramid: base 2 x levels - 1) | " + " | ".join(f"{n} levels" for n in levels) + " |")
    print("|---|---:|" + "---:|" * len(levels))
    for name, offsets in (("every neighbour", OFFSETS), ("axes only", np.eye(3, dtype=np.int64))):
        for width in widths:
            forces = [float(np.nanmax(joint_forces(solid_block(width, n, offsets), physics))) for n in levels]
            marked = [f"{f:.0f}" if f <= physics.break_force else f"**{f:.0f}**" for f in forces]
            shape = "pyramid" if width is None else width
            print(f"| {name} | {shape} | " + " | ".join(marked) + " |", flush=True)


def print_rules(levels: range = range(2, 9), beam: int = 10, max_vertices: int = 500) -> None:
    physics = PhysicsConfig()
    print(f"largest static joint load (N) of the best level-by-level rule; joints break above {physics.break_force:g} N")
    print()
    print("| levels | rules, top level first | tied levels | vertices | edges | largest static load | peak in the first 0.3 s |")
    print("|---:|---|---:|---:|---:|---:|---:|")
    kept: list[tuple[str, ...]] = [()]
    for n in levels:
        scored = []
        for rules, tied, design in by_level_rules_one_taller(kept, max_vertices):
            scored.append((largest_static_load(design, physics), rules, tied, design))
        if not scored:
            print(f"| {n} | none within {max_vertices} vertices | | | | | |")
            break
        scored.sort(key=lambda row: row[0])
        load, rules, tied, design = scored[0]
        peak = transient_peak(design)
        shown = [f"{f:.1f} N" if f <= physics.break_force else f"**{f:.1f} N**" for f in (load, peak)]
        print(
            f"| {n} | {' '.join(rules)} | {tied} | {design.n_vertices} | {design.n_edges} | {shown[0]} | {shown[1]} |",
            flush=True,
        )
        kept = list(dict.fromkeys(row[1] for row in scored))[:beam]


if __name__ == "__main__":
    main()
