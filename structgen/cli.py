"""The ``structgen`` command line: thin wrappers over library functions that scripts can call directly.

Results go to stdout, logs to stderr. Exit codes: 0 success, 1 runtime failure, 2 bad input or usage (a one-line
message naming the file and the problem; ``--verbose`` adds the traceback). Nothing is written when input is bad.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from structgen import __version__
from structgen.structure import Structure, StructureError

log = logging.getLogger("structgen")

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2


class InputError(Exception):
    """Bad input from the user (a file, an option value); reported in one line with exit code 2."""


# -- shared option groups ---------------------------------------------------------------------------------------------
def _add_mesh_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("mesh dimensions (mesh formats only; defaults match the physics model)")
    group.add_argument("--sphere-radius", type=float, metavar="R", help="radius of the vertex spheres (default 0.25)")
    group.add_argument("--cylinder-radius", type=float, metavar="R", help="radius of the edge cylinders (default 0.08)")
    group.add_argument("--spacing", type=float, metavar="S", help="world length of one lattice step (default 1.0)")
    group.add_argument(
        "--sphere-subdivisions",
        type=int,
        metavar="N",
        help="icosphere subdivisions of each sphere, 0..5 (default 2: 320 triangles; 0 gives 20, for big structures)",
    )
    group.add_argument(
        "--cylinder-sections", type=int, metavar="N", help="sides of each cylinder, 3..128 (default 12; 6 for big structures)"
    )


def _mesh_options(args: argparse.Namespace) -> dict[str, float]:
    names = {
        "sphere_radius": args.sphere_radius,
        "cylinder_radius": args.cylinder_radius,
        "spacing": args.spacing,
        "sphere_subdivisions": args.sphere_subdivisions,
        "cylinder_sections": args.cylinder_sections,
    }
    return {name: value for name, value in names.items() if value is not None}


def _add_nca_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("NCA (defaults follow the paper)")
    group.add_argument("--iterations", type=int, metavar="N", help="growth steps from the seed vertex (default 5)")
    group.add_argument("--cutoff", type=float, metavar="X", help="an output fires above this sigmoid value (default 0.5)")
    group.add_argument("--hidden", type=int, metavar="N", help="hidden layer size (default 60)")
    group.add_argument(
        "--no-build-down", action="store_true", help="never grow below the seed's level (the paper's special rule)"
    )
    group.add_argument("--max-vertices", type=int, metavar="N", help="stop growth before exceeding this (default 10000)")
    group.add_argument("--max-extent", type=int, metavar="N", help="never build further than N cells from the seed (default 32)")


def _nca_changes(args: argparse.Namespace) -> dict[str, Any]:
    """The NCA settings given on the command line (only those given)."""
    options = {
        "iterations": args.iterations,
        "cutoff": args.cutoff,
        "hidden": args.hidden,
        "max_vertices": args.max_vertices,
        "max_extent": args.max_extent,
    }
    changes: dict[str, Any] = {name: value for name, value in options.items() if value is not None}
    if args.no_build_down:
        changes["build_down"] = False
    return changes


def _nca_config(args: argparse.Namespace):
    from structgen.nca import NCAConfig

    try:
        return NCAConfig(**_nca_changes(args))
    except ValueError as err:
        raise InputError(str(err)) from None


def _load_structure(path: str) -> Structure:
    source = Path(path)
    if source.is_dir():
        raise InputError(f"{source}: is a folder, expected a structure JSON file")
    return Structure.load(source)


def _write(structure: Structure, output: str, mesh: dict[str, float]) -> Path:
    path = Path(output)
    if path.is_dir():
        raise InputError(f"{path}: is a folder, expected an output file name")
    if mesh and path.suffix.lower() == ".json":
        raise InputError(f"{path}: mesh dimensions only apply to mesh formats (.glb, .obj, .stl, .ply)")
    return structure.export(path, **mesh)


def _add_physics_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("physics")
    group.add_argument(
        "--preset",
        choices=("faithful", "fast"),
        default="faithful",
        help="faithful: the paper's protocol (1/240 s steps, 50 solver iterations, 30 s); fast: 1/120 s, "
        "20 iterations, stop when settled, at most 2 s (default faithful)",
    )
    group.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change one physics setting, e.g. --set break_force=60 --set horizon=10 (repeatable; see README)",
    )
    group.add_argument(
        "--statics",
        action="store_true",
        help="predict with the static frame solve (milliseconds, no size cap) instead of simulating",
    )


def _physics_config(args: argparse.Namespace):
    from physics import PhysicsConfig

    from structgen.config import ConfigError, apply_overrides

    try:
        return apply_overrides(PhysicsConfig.preset(args.preset), args.set, "physics")
    except ConfigError as err:
        raise InputError(str(err)) from None


def _checked(args: argparse.Namespace):
    """Load the file, simulate it, and return (structure, report); size caps and bad files are input errors."""
    from physics import InputError as PhysicsInputError
    from physics import check_stability, check_statics

    config = _physics_config(args)
    structure = _load_structure(args.file)
    try:
        return structure, (check_statics if args.statics else check_stability)(structure, config)
    except PhysicsInputError as err:
        raise InputError(f"{args.file}: {err}") from None


def _describe(structure: Structure) -> str:
    return f"{structure.n_vertices} vertices, {structure.n_edges} edges, height {structure.height}"


# -- subcommands --------------------------------------------------------------------------------------------------------
def cmd_grow(args: argparse.Namespace) -> int:
    from structgen.nca import LocalNCA, load_weights

    mesh = _mesh_options(args)
    if args.run:
        nca = _run_nca(args)
        origin: dict[str, Any] = {"run": str(args.run), "elite": args.elite}
    else:
        config = _nca_config(args)
        if args.weights:
            try:
                nca = LocalNCA(load_weights(args.weights, config), config)
            except ValueError as err:
                raise InputError(str(err)) from None
            origin = {"weights_file": str(args.weights)}
        else:
            nca = LocalNCA.random(args.seed, config)
            origin = {"random_seed": args.seed}
    started = time.perf_counter()
    structure = nca.grow()
    log.info("grew %d vertices and %d edges in %.2f s", structure.n_vertices, structure.n_edges, time.perf_counter() - started)
    growth = structure.metadata["growth"]
    if growth["hit_max_vertices"]:
        log.warning("growth stopped after %d steps at --max-vertices %d", growth["iterations_run"], nca.config.max_vertices)
    if growth["hit_max_extent"]:
        log.warning("some growth was dropped at --max-extent %d", nca.config.max_extent)
    structure = structure.with_metadata(**origin)
    path = _write(structure, args.output, mesh)
    print(f"{path}: {_describe(structure)}")
    return EXIT_OK


def _run_nca(args: argparse.Namespace):
    """The NCA of a run's elite, with the run's NCA settings changed by any NCA options given."""
    from dataclasses import replace

    from structgen.nca import LocalNCA
    from structgen.runs import elite_genome, open_run

    folder, experiment = open_run(args.run)
    if experiment.problem_name != "structures":
        raise InputError(f"{args.run}: a run of the {experiment.problem_name!r} problem has no NCA to grow")
    try:
        config = replace(experiment.problem_settings.nca, **_nca_changes(args))
        return LocalNCA(elite_genome(folder, experiment, args.elite), config)
    except ValueError as err:
        raise InputError(str(err)) from None


def cmd_export(args: argparse.Namespace) -> int:
    output = args.output_option or args.output
    if not output:
        raise InputError("export needs an output file: structgen export SOURCE OUT (or -o OUT)")
    if args.output_option and args.output:
        raise InputError("give the output file once, either as OUT or as -o OUT")
    source = Path(args.source)
    if source.is_dir():
        structure = _run_elite(source, args.elite)
    else:
        if args.elite != "best":
            raise InputError("--elite only applies to run folders")
        structure = _load_structure(args.source)
    path = _write(structure, output, _mesh_options(args))
    print(f"{path}: {_describe(structure)}")
    return EXIT_OK


def _run_elite(run_dir: Path, elite: str) -> Structure:
    from structgen.runs import elite_genome, open_run

    folder, experiment = open_run(run_dir)
    problem = experiment.make_problem()
    if not hasattr(problem, "structure_of"):
        raise InputError(f"{run_dir}: a run of the {experiment.problem_name!r} problem has no structures to export")
    genome = elite_genome(folder, experiment, elite)
    return problem.structure_of(genome).with_metadata(run=str(run_dir), elite=elite)


def cmd_info(args: argparse.Namespace) -> int:
    structure = _load_structure(args.file)
    summary = {"file": str(args.file), **structure.summary()}
    if args.json:
        print(json.dumps(summary))
        return EXIT_OK
    low, high = summary["bounds"]["min"], summary["bounds"]["max"]
    rows = [
        ("file", summary["file"]),
        ("vertices", summary["vertices"]),
        ("edges", summary["edges"]),
        ("height", summary["height"]),
        ("bounds", f"{low} .. {high}"),
        ("components", summary["components"]),
        ("isolated", summary["isolated_vertices"]),
        ("max degree", summary["max_degree"]),
    ]
    for name, value in rows:
        print(f"{name:<11} {value}")
    return EXIT_OK


def cmd_check(args: argparse.Namespace) -> int:
    _, report = _checked(args)
    if args.json:
        print(json.dumps({"file": str(args.file), **report.to_dict()}))
    else:
        broken = len(report.broken_joints)
        verdict = "stands (no joint broke)" if report.intact else f"breaks ({broken} of {report.n_joints} joints broke)"
        if report.exploded:
            verdict = "the simulation exploded (scored as collapsed)"
        statics = report.method == "statics"
        rows = [
            ("file", args.file),
            ("method", "static frame solve" if statics else "simulation (PyBullet)"),
            # The static analysis reads only masses, sizes and the break force from the settings, not the preset's
            # time stepping.
            ("settings", f"{report.config.preset_name} preset" if report.config.preset_name else f"{args.preset} preset, customised"),
            ("verdict", verdict),
            ("integrity", f"{report.integrity:.4f}"),
            ("height", f"{report.height:.3f}"),
            ("complexity", report.complexity),
            ("score", f"{report.score:.4f}"),
            ("solved", f"{report.steps} failure rounds")
            if statics
            else ("simulated", f"{report.sim_time:.2f} s, {report.steps} steps, " + ("settled" if report.settled else "not settled")),
            ("cpu", f"{report.cpu_time:.3f} s"),
        ]
        for name, value in rows:
            print(f"{name:<11} {value}")
        for joint in report.broken_joints[:10]:
            when = f"in round {joint.time:.0f}" if statics else f"at {joint.time:.3f} s"
            print(f"broken      joint {joint.joint} (edge {joint.edge}, vertex {joint.vertex}) {when}, {joint.force:.1f} N")
        if broken > 10:
            print(f"broken      ... and {broken - 10} more (--json lists all)")
    if args.strict and not report.intact:
        return EXIT_FAILURE
    return EXIT_OK


def cmd_render(args: argparse.Namespace) -> int:
    from structgen.render import render_check

    output = Path(args.output)
    if output.suffix.lower() != ".png":
        raise InputError(f"{output}: render writes PNG images; give a name ending in .png")
    _, report = _checked(args)
    render_check(report, output, dpi=args.dpi)
    print(f"{output}: {'stands' if report.intact else 'breaks'}, I = {report.integrity:.3f}, Q = {report.score:.3f}")
    return EXIT_OK


def _report_run(folder, state) -> None:
    best = state.best
    print(f"{folder.path}: {state.generation} generations, {state.evaluations} evaluations, {state.elapsed:.1f} s")
    if best is not None:
        details = ", ".join(f"{k} {v:g}" for k, v in best.fields.items())
        print(f"best: objective {best.objective:g} (generation {best.generation}); {details}")


def cmd_evolve(args: argparse.Namespace) -> int:
    from evolution import graceful_interrupt

    from structgen.experiment import load_experiment
    from structgen.runs import evolve

    changes = {"generations": args.generations, "seed": args.seed, "workers": args.workers, "cluster": args.cluster}
    overrides = [*args.set, *([f"problem.evaluator={args.evaluator}"] if args.evaluator else [])]
    experiment = load_experiment(args.config, overrides=overrides, optimizer=args.optimizer, run_changes=changes)
    with graceful_interrupt() as stop:
        folder, state = evolve(experiment, args.run_dir, overwrite=args.overwrite, stop_requested=stop)
        _report_run(folder, state)
        return 130 if stop() else EXIT_OK


def cmd_resume(args: argparse.Namespace) -> int:
    from evolution import graceful_interrupt

    from structgen.runs import resume

    with graceful_interrupt() as stop:
        folder, state = resume(
            args.run_dir, generations=args.generations, workers=args.workers, cluster=args.cluster, stop_requested=stop
        )
        _report_run(folder, state)
        return 130 if stop() else EXIT_OK


# -- parser -------------------------------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="structgen",
        description="Grow 3D lattice structures with neural cellular automata, export them, inspect them, and check "
        "whether they stand under gravity.",
    )
    parser.add_argument("--version", action="version", version=f"structgen {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log more, and show tracebacks on errors")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    grow = commands.add_parser(
        "grow",
        help="grow a structure from a random or saved NCA",
        description="Grow a structure from one seed vertex with the paper's local NCA and write it to OUT "
        "(structure JSON, or a mesh: .glb, .obj, .stl, .ply).",
    )
    source = grow.add_mutually_exclusive_group()
    source.add_argument("--seed", type=int, default=0, metavar="N", help="random NCA drawn with this seed (default 0)")
    source.add_argument("--weights", metavar="FILE", help="NCA weights: .npy (1-D array) or .json (list of numbers)")
    source.add_argument(
        "--run",
        metavar="RUN_DIR",
        help="an evolution run's NCA (its settings, then any NCA options given here, e.g. more --iterations)",
    )
    grow.add_argument("--elite", default="best", metavar="best|index:I", help="with --run: which NCA (default best)")
    grow.add_argument("-o", "--output", required=True, metavar="OUT", help="output file; format from the suffix")
    _add_nca_options(grow)
    _add_mesh_options(grow)
    grow.set_defaults(handler=cmd_grow)

    export = commands.add_parser(
        "export",
        help="write a structure file, or an elite of a run, as a mesh",
        description="Write the structure in SOURCE (a structure JSON file, or a run folder's best candidate or "
        "archive elite, regrown from its genome) to OUT; the format follows OUT's suffix "
        "(.glb y-up with metadata, .obj, .stl, .ply, or .json).",
    )
    export.add_argument("source", metavar="SOURCE", help="structure JSON file or run folder")
    export.add_argument("output", nargs="?", metavar="OUT", help="output file (or use -o)")
    export.add_argument("-o", dest="output_option", metavar="OUT", help="output file")
    export.add_argument(
        "--elite",
        default="best",
        metavar="best|index:I",
        help="for a run folder: the best candidate (default) or the archive elite in cell I (see archive.csv)",
    )
    _add_mesh_options(export)
    export.set_defaults(handler=cmd_export)

    info = commands.add_parser(
        "info",
        help="print counts, height and connectivity of a structure",
        description="Print a structure's vertex and edge counts, height, bounding box and connected components.",
    )
    info.add_argument("file", metavar="FILE", help="structure JSON file")
    info.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    info.set_defaults(handler=cmd_info)

    check = commands.add_parser(
        "check",
        help="simulate a structure under gravity and report whether it stands",
        description="Build FILE as rigid bodies (a sphere per vertex, a cylinder per edge, breakable fixed joints), "
        "rest it on the ground under gravity, and report integrity I (share of joints unbroken), height H, "
        "complexity C (vertex count) and the score Q = I + (Wh*H + Wc*C)*I. Exits 0 whether or not it stands "
        "(1 with --strict if it breaks).",
    )
    check.add_argument("file", metavar="FILE", help="structure JSON file")
    check.add_argument("--json", action="store_true", help="print the whole report as one JSON object")
    check.add_argument("--strict", action="store_true", help="exit with 1 if any joint breaks")
    _add_physics_options(check)
    check.set_defaults(handler=cmd_check)

    render = commands.add_parser(
        "render",
        help="draw a structure before and after its stability check",
        description="Judge FILE as 'check' does (by simulation, or by the static analysis with --statics) and draw "
        "it as placed and as it ended up, broken joints in red, to a PNG image (no display needed).",
    )
    render.add_argument("file", metavar="FILE", help="structure JSON file")
    render.add_argument("-o", "--output", required=True, metavar="OUT.png", help="image to write")
    render.add_argument("--dpi", type=int, default=110, help="image resolution (default 110)")
    _add_physics_options(render)
    render.set_defaults(handler=cmd_render)

    evolve = commands.add_parser(
        "evolve",
        help="run an evolution (with no arguments: the README's main job)",
        description="Evolve with the configuration in CONFIG (TOML with [run], [problem] and [optimizer] tables), "
        "or, without CONFIG, the built-in main job: the paper's setup scaled to a few minutes (GA, population 40, "
        "NCA vertex cap 64, fast physics). Writes a run folder: config.toml, manifest.json, checkpoint.pkl, "
        "metrics.jsonl, best/, plots, and archive.csv for quality diversity. Ctrl-C finishes the generation, "
        "checkpoints and exits (130); `structgen resume` continues.",
    )
    evolve.add_argument("config", nargs="?", metavar="CONFIG.toml", help="run configuration (default: the main job)")
    evolve.add_argument("--optimizer", metavar="NAME", help="ga, cma_es, map_elites or cma_mae (sets optimizer.name)")
    evolve.add_argument("--generations", type=int, metavar="N", help="generations in total (sets run.generations)")
    evolve.add_argument("--seed", type=int, metavar="N", help="the run's seed (sets run.seed)")
    evolve.add_argument("--workers", type=int, metavar="N", help="local evaluation processes, 0 for none (run.workers)")
    evolve.add_argument("--cluster", metavar="ADDRESS", help="evaluate on the Dask scheduler at ADDRESS (run.cluster)")
    evolve.add_argument(
        "--evaluator",
        choices=("bullet", "statics", "statics+bullet"),
        help="judge structures by simulation, by the static frame solve, or statics first and the simulation for "
        "those predicted to stand (sets problem.evaluator)",
    )
    evolve.add_argument("--run-dir", metavar="DIR", help="run folder to create (default runs/<problem>-<optimizer>-s<seed>-<time>)")
    evolve.add_argument("--overwrite", action="store_true", help="replace RUN_DIR if it is already a run folder")
    evolve.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change any setting by its dotted name, e.g. optimizer.population=100, problem.nca.cutoff=0.6, "
        "problem.physics.preset=faithful (repeatable)",
    )
    evolve.set_defaults(handler=cmd_evolve)

    resume = commands.add_parser(
        "resume",
        help="continue a run from its last checkpoint",
        description="Continue the run in RUN_DIR from its last checkpoint, reading only its config.toml; the result "
        "is the same as if it had never stopped.",
    )
    resume.add_argument("run_dir", metavar="RUN_DIR", help="run folder")
    resume.add_argument("--generations", type=int, metavar="N", help="run up to N generations in total (default: as configured)")
    resume.add_argument("--workers", type=int, metavar="N", help="local evaluation processes this time (results do not change)")
    resume.add_argument("--cluster", metavar="ADDRESS", help="evaluate on this Dask scheduler this time")
    resume.set_defaults(handler=cmd_resume)
    return parser


def _report(message: str) -> None:
    print(f"structgen: error: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    # Our packages talk at INFO; third-party libraries (matplotlib, dask) only when something is wrong.
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s: %(message)s", stream=sys.stderr, force=True)
    for name in ("structgen", "physics", "evolution"):
        logging.getLogger(name).setLevel(logging.DEBUG if args.verbose else logging.INFO)
    handler: Callable[[argparse.Namespace], int] = args.handler
    from structgen.config import ConfigError

    try:
        return handler(args)
    except (InputError, StructureError, ConfigError) as err:
        _report(str(err))
    except FileNotFoundError as err:
        _report(f"{err.filename}: no such file")
    except (IsADirectoryError, PermissionError) as err:
        _report(f"{err.filename}: {err.strerror.lower()}")
    except KeyboardInterrupt:
        _report("interrupted")
        return 130
    except Exception as err:  # a bug or an environment failure, not the user's input
        if type(err).__name__ == "RunFolderError":  # a missing or unusable run folder is the user's input
            _report(str(err))
            return EXIT_BAD_INPUT
        _report(f"{type(err).__name__}: {err}")
        if args.verbose:
            traceback.print_exc()
        return EXIT_FAILURE
    if args.verbose:
        traceback.print_exc()
    return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
