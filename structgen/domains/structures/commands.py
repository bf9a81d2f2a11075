"""The structures domain's verbs: ``grow``, ``evaluate``, ``show``, ``teach``, ``tall``, what ``info`` says of a
structure, and exports of structures as meshes.

``structgen structures <verb>``, and at the top level too (``structgen grow``): they are the product's face. Every
verb takes ``--set`` with the same grammar as ``structgen evolve``; its named options are shortcuts for settings
(``--cutoff 0.6`` is ``--set nca.cutoff=0.6``).
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from physics.config import PhysicsConfig
from structgen.domains.structures.experiment import EXPERIMENTS
from structgen.domains.structures.regrow import CUTS
from structgen.domains.structures.tall_settings import TallSettings
from structgen.mesh import MeshStyle
from structgen.nca_config import NCAConfig, grow_command
from structgen.registry.commands import (
    EXIT_FAILURE,
    EXIT_OK,
    Adder,
    DomainCommands,
    InputError,
    dpi,
    flag,
    group,
    json_flag,
    nca_weights,
    number,
    one_of,
    option,
    output,
    output_folder,
    output_path,
    overwrite,
    png_output_path,
    print_table,
    real,
    seed,
    seed_run_options,
    set_option,
    settings,
    settings_from_args,
    verb,
    verbs,
    whole_number,
    workers,
)
from structgen.structure import Structure

__all__ = ["COMMANDS", "StructureCommands"]

log = logging.getLogger("structgen")

# Options that stand for settings: the option's dest, then the dotted setting it sets.
MESH_OPTIONS = {
    "sphere_radius": "mesh.sphere_radius",
    "cylinder_radius": "mesh.cylinder_radius",
    "spacing": "mesh.spacing",
    "sphere_subdivisions": "mesh.sphere_subdivisions",
    "cylinder_sections": "mesh.cylinder_sections",
}
NCA_OPTIONS = {
    "iterations": "nca.iterations",
    "cutoff": "nca.cutoff",
    "hidden": "nca.hidden",
    "build_down": "nca.build_down",
    "max_vertices": "nca.max_vertices",
    "max_extent": "nca.max_extent",
}


# -- helpers ------------------------------------------------------------------------------------------------------------
def _mesh_style(args: argparse.Namespace) -> Any:
    from structgen.mesh import MeshStyle

    return settings_from_args({"mesh": MeshStyle()}, args, MESH_OPTIONS)["mesh"]


def _stress_physics(args: argparse.Namespace, physics: Any = None) -> Any:
    """The physics ``--stress`` colours by (None without it): a run's own, else the default."""
    if not getattr(args, "stress", False):
        return None
    from physics import PhysicsConfig

    return physics or PhysicsConfig()


def _load_structure(path: str | Path) -> Structure:
    source = Path(path)
    if source.is_dir():
        raise InputError(f"{source}: is a folder, expected a structure JSON file")
    return Structure.load(source)


def _write(structure: Structure, output: str | Path, style: Any, solid: bool = False, stress: Any = None) -> Path:
    """Write ``structure`` to ``output``; ``stress``, a physics config: members in their load colours (``--stress``)."""
    from dataclasses import asdict

    from structgen.mesh import MeshStyle

    path = Path(output)
    if path.is_dir():
        raise InputError(f"{path}: is a folder, expected an output file name")
    default = asdict(MeshStyle())
    changed = {name: value for name, value in asdict(style).items() if value != default[name]}
    if (changed or solid or stress is not None) and path.suffix.lower() == ".json":
        raise InputError(f"{path}: mesh options (dimensions, --solid, --stress) only apply to mesh formats "
                         "(.glb, .obj, .stl, .ply)")  # fmt: skip
    if stress is None:
        return structure.export(path, solid=solid, **changed)
    if solid:
        raise InputError(f"{path}: --stress colours each member, and a --solid shell is one piece of one colour")
    if path.suffix.lower() == ".stl":
        raise InputError(f"{path}: STL holds no colours; write --stress to .glb, .obj or .ply")
    from structgen.domains.structures.stress import load_colours, load_key, member_load_shares

    _, shares = member_load_shares(structure, stress)
    return structure.export(path, edge_colors=load_colours(shares), colour_key=load_key(shares, stress), **changed)


def _describe(structure: Structure) -> str:
    return f"{structure.n_vertices} vertices, {structure.n_edges} edges, height {structure.height}"


def _physics_config(args: argparse.Namespace) -> Any:
    from physics import PhysicsConfig

    return settings_from_args({"physics": PhysicsConfig()}, args, {"preset": "physics.preset"})["physics"]


def _checked(args: argparse.Namespace) -> tuple[Structure, Any]:
    """Load the file, judge it, and return (structure, report); size caps and bad files are input errors."""
    from physics import InputError as PhysicsInputError
    from physics import check_stability, check_statics, check_transient

    config = _physics_config(args)
    structure = _load_structure(args.file)
    if args.transient and args.transient < config.timestep:
        raise InputError(f"--transient {args.transient:g}: shorter than one physics step ({config.timestep:g} s)")
    try:
        if args.transient:
            return structure, check_transient(structure, config, window=args.transient)
        return structure, (check_statics if args.statics else check_stability)(structure, config)
    except PhysicsInputError as err:
        raise InputError(f"{args.file}: {err}") from None


# -- verbs --------------------------------------------------------------------------------------------------------------
def cmd_grow(args: argparse.Namespace) -> int:
    """grow a structure from a random or saved NCA

    Grow a structure from one seed vertex with the paper's local NCA and write it to OUT (structure JSON, or a mesh:
    .glb, .obj, .stl, .ply).
    """
    from structgen.mesh import MeshStyle
    from structgen.nca import LocalNCA, NCAConfig, load_weights

    if args.run:
        weights, nca_base, origin = _run_nca(args)
    else:
        weights, nca_base = None, NCAConfig()
        origin = {"weights_file": str(args.weights)} if args.weights else {"random_seed": args.seed}
    settings = settings_from_args({"nca": nca_base, "mesh": MeshStyle()}, args, {**NCA_OPTIONS, **MESH_OPTIONS})
    config = settings["nca"]
    try:
        if args.run:
            nca = LocalNCA(weights, config)
        elif args.weights:
            nca = LocalNCA(load_weights(args.weights, config), config)
        else:
            nca = LocalNCA.random(args.seed, config)
    except ValueError as err:
        raise InputError(str(err)) from None
    started = time.perf_counter()
    if args.frames or args.gif:
        from structgen.domains.structures.render import render_growth
        from structgen.nca import grow_steps

        frames = grow_steps(nca.get_weights(), config)
        structure = frames[-1]
        pictures = render_growth(frames, folder=args.frames, gif=args.gif)
        log.info("drew %d growth steps: %s", len(frames), ", ".join(str(p) for p in pictures[-1:] + pictures[:1]))
    else:
        structure = nca.grow()
    log.info("grew %d vertices and %d edges in %.2f s", structure.n_vertices, structure.n_edges, time.perf_counter() - started)
    growth = structure.metadata["growth"]
    if growth["reached_fixed_point"]:
        log.info("growth reached a fixed point after %d steps: further steps change nothing", growth["iterations_run"])
    if growth["hit_max_vertices"]:
        log.warning("growth stopped after %d steps at --max-vertices %d", growth["iterations_run"], config.max_vertices)
    if growth["hit_max_extent"]:
        log.warning("some growth was dropped at --max-extent %d", config.max_extent)
    structure = structure.with_metadata(**origin)
    path = _write(structure, args.output, settings["mesh"], args.solid, _stress_physics(args))
    print(f"{path}: {_describe(structure)}")
    return EXIT_OK


def _frames_folder(text: str) -> Path:
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: --frames names a folder to draw the steps in, and this is a file")
    return path


def _gif_path(text: str) -> Path:
    path = output_path(text)
    if path.suffix.lower() != ".gif":
        raise argparse.ArgumentTypeError(f"{text}: --gif writes an animated GIF; give a name ending in .gif")
    return path


def _run_nca(args: argparse.Namespace) -> tuple[Any, Any, dict[str, Any]]:
    """The weights of a run's elite, the run's NCA settings, and where they came from."""
    from structgen.domains.structures import DOMAIN
    from structgen.runs import elite_genome, open_run

    folder, experiment = open_run(args.run)
    if experiment.domain != DOMAIN.id:
        raise InputError(f"{args.run}: a run of the {experiment.domain} domain has no NCA to grow")
    problem = experiment.make_problem()
    try:
        genome = elite_genome(folder, problem, args.elite)
    finally:
        problem.close()
    return genome, experiment.problem_settings.nca, {"run": str(args.run), "elite": args.elite}


def describe_structure(path: Path) -> tuple[dict[str, Any], str] | None:
    """``structgen info`` on a structure file, or on a tall search folder of structgen 0.2 (no manifest); None for a
    folder that is neither (a run folder: the generic ``info`` describes it)."""
    from structgen.domains.structures.tall import describe_search, is_search_folder, search_summary

    if path.is_dir():
        if not is_search_folder(path):
            return None
        summary = search_summary(path)
        return summary, describe_search(summary)
    structure = _load_structure(path)
    summary = {"file": str(path), **structure.summary()}
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
    return summary, "\n".join(f"{name:<11} {value}" for name, value in rows)


_METHODS = {
    "bullet": "simulation (PyBullet)",
    "statics": "static frame solve",
    "transient": "first moments simulated with joints that hold (PyBullet); integrity is the strength ratio",
}


def cmd_check(args: argparse.Namespace) -> int:
    """simulate a structure under gravity and report whether it stands

    Build FILE as rigid bodies (a sphere per vertex, a cylinder per edge, breakable fixed joints), rest it on the
    ground under gravity, and report integrity I (share of joints unbroken), height H, complexity C (vertex count)
    and the score Q = I + (Wh*H + Wc*C)*I. Exits 0 whether or not it stands (1 with --strict unless it stands: no
    joint broke and it came to rest).
    """
    _, report = _checked(args)
    if args.json:
        print(json.dumps({"file": str(args.file), **report.to_dict()}))
    else:
        broken = len(report.broken_joints)
        verdict = report.verdict()
        statics = report.method == "statics"
        preset = report.config.preset_name
        rows = [
            ("file", args.file),
            ("method", _METHODS[report.method]),
            # The static analysis reads only masses, sizes and the break force from the settings, not the preset's
            # time stepping.
            ("settings", f"{preset} preset" if preset else "customised (--json lists every setting)"),
            ("verdict", verdict),
            ("integrity", f"{report.integrity:.4f}"),
            ("height", f"{report.height:.3f}"),
            ("complexity", report.complexity),
            ("score", f"{report.score:.4f}"),
            ("solved", f"{report.steps} failure rounds")
            if statics
            else (
                "simulated",
                f"{report.sim_time:.2f} s, {report.steps} steps, " + ("settled" if report.settled else "not settled"),
            ),
            ("cpu", f"{report.cpu_time:.3f} s"),
        ]
        if report.method == "transient":
            rows.insert(5, ("peak force", f"{report.peak_force:.1f} N (break force {report.config.break_force:g} N)"))
        for name, value in rows:
            print(f"{name:<11} {value}")
        limit = report.config.break_force
        fell = sum(joint.fell for joint in report.broken_joints)
        if statics and broken:
            print(
                f"{'overloaded':<11} {broken - fell} joints (listed first, each with the load that broke it, the load "
                f"factors applied), then {fell} fell with their pieces"
            )
        # The overloaded joints are the cause; those that fell with their pieces follow.
        for joint in sorted(report.broken_joints, key=lambda j: (j.fell, j.time))[:10]:
            when = f"in round {joint.time:.0f}" if statics else f"at {joint.time:.3f} s"
            load = f"{joint.force:.1f} N"
            if joint.fell:  # its force was within the limit: say why it counts as broken
                load += f" (within the {limit:g} N limit: the piece it holds lost its support or tipped, and falls)"
            print(f"broken      joint {joint.joint} (edge {joint.edge}, vertex {joint.vertex}) {when}, {load}")
        if broken > 10:
            print(f"broken      ... and {broken - 10} more (--json lists all)")
    if args.strict and not report.stands:
        return EXIT_FAILURE
    return EXIT_OK


def cmd_render(args: argparse.Namespace) -> int:
    """draw a structure before and after its stability check

    Judge FILE as 'evaluate' does (by simulation, or by the static analysis with --statics) and draw it as placed and
    as it ended up, broken joints in red, to a PNG image (no display needed).
    """
    from structgen.domains.structures.render import render_check

    output = Path(args.output)
    if args.peaks and (args.stress or args.statics):
        raise InputError("--peaks colours members by a simulation's forces: it takes neither --stress (the static "
                         "analysis's loads) nor --statics (no simulation)")  # fmt: skip
    structure, report = _checked(args)
    shares, label = None, "member load"
    if args.stress:
        from structgen.domains.structures.stress import member_load_shares

        _, shares = member_load_shares(structure, _physics_config(args))
    elif args.peaks:
        from structgen.domains.structures.stress import member_peak_shares

        shares, label = member_peak_shares(report), "largest force in the simulation"
    render_check(report, output, dpi=args.dpi, load_shares=shares, load_label=label)
    print(f"{output}: {report.verdict()}; I = {report.integrity:.3f}, Q = {report.score:.3f}")
    return EXIT_OK


# -- the hooks ----------------------------------------------------------------------------------------------------------
def cmd_regrow(args: argparse.Namespace) -> int:
    """cut members out of a structure an NCA grew and let the same NCA grow on

    Remove --damage of FILE's members (--cut mid: those nearest its middle height; random: drawn at random), let the
    NCA in --weights grow on from what is left for its growth steps (or until nothing changes), and print the share
    of the original's members that came back, how many members grew that it lacked, and whether the regrown structure
    stands (the static analysis, faithful preset; with --transient also PyBullet's first 0.3 s). The NCA's settings
    are those FILE was grown with (its growth metadata), where not given here.
    """
    from structgen.domains.structures.regrow import regrow
    from structgen.nca import load_weights

    if args.weights is None:
        raise InputError("regrow needs the NCA that grew FILE: --weights FILE.npy")
    from structgen.config import build

    structure = _load_structure(args.file)
    growth = structure.metadata.get("growth", {})
    if not isinstance(growth, dict):
        raise InputError(f"{args.file}: metadata.growth is {type(growth).__name__}, not the table of settings it was grown with")
    grown_with = {name: growth[name] for name in NCA_OPTIONS if name in growth}
    # The file's settings are checked as a configuration's are (type and range, named), before the options apply.
    try:
        config = build(NCAConfig, grown_with, f"{args.file}: metadata.growth")
    except InputError as err:
        raise InputError(str(err) if str(args.file) in str(err) else f"{args.file}: metadata.growth: {err}") from None
    config = settings_from_args({"nca": config}, args, NCA_OPTIONS)["nca"]
    try:
        result = regrow(load_weights(args.weights, config), structure, config, args.damage, args.cut, args.seed)
    except ValueError as err:
        raise InputError(f"{args.file}: {err}") from None
    summary = {
        "file": str(args.file), "damage": args.damage, "cut": args.cut, "members": structure.n_edges,
        "cut_out": structure.n_edges - result.damaged.n_edges, "regrown_members": result.regrown.n_edges,
        "restored": result.restored, "extra": result.extra, "stands": result.stands,
    }  # fmt: skip
    verdict = ("stands" if result.stands else "does not stand") + " (static analysis, faithful preset)"
    if args.transient:
        from physics import PhysicsConfig
        from structgen.domains.structures.tall import transient_peak

        limit = PhysicsConfig().break_force
        summary["transient_peak"] = peak = transient_peak(result.regrown)
        summary["holds_in_transient"] = holds = peak <= limit  # as a transient report counts it intact
        verdict += f"; in PyBullet's first 0.3 s its largest joint force is {peak:.1f} N of {limit:g} N: " + (
            "it holds" if holds else "it breaks"
        )
    if args.output:
        _write(result.regrown.with_metadata(regrown_from=str(args.file)), args.output, MeshStyle())
    if args.picture:
        from structgen.domains.structures.render import render_regrowth

        cut = f"{args.cut} cut of {args.damage:.0%}"
        render_regrowth(result.original, result.damaged, result.regrown, args.picture, cut=cut)
    if args.json:
        print(json.dumps(summary))
    else:
        print(
            f"{args.file}: cut {summary['cut_out']} of {structure.n_edges} members ({args.cut}); the NCA regrew "
            f"{result.restored:.1%} of the original's members and {result.extra} it lacked; the regrown structure {verdict}"
        )
    return EXIT_OK


def cmd_design(args: argparse.Namespace) -> int:
    """grow a structure to a spec: a footprint, a height, a member budget

    Return a structure grown by an NCA of the design library that meets the spec exactly (--footprint W x D cells on
    the ground, --height H levels, at most --max-members edges) and that the static analysis (faithful preset) finds
    standing, in milliseconds; the library's answers that the static analysis loads near the break force were also
    simulated for PyBullet's first 0.3 s when it was built, and those that break there left out. --seed picks among
    the library's answers for the spec. A spec no answer meets is an error naming the nearest spec that can be met.
    Some specs are met by a tower of a smaller footprint standing on a floor mat that fills the spec's: such an answer
    is given only where no answer that fills the footprint stands, and the output says so (--json: "on_mat", and
    "above_ground", the footprint of the levels above the ground); --no-mat refuses them.
    Writes OUT by its suffix (json, glb, obj, stl, ply).
    """
    from structgen.domains.structures.design import Spec, UnmeetableSpec, design, dimensions, load_library
    from structgen.domains.structures.stress import member_load_shares

    width, depth = args.footprint
    try:
        spec = Spec(width, depth, args.height, args.max_members)
    except ValueError as err:
        raise InputError(str(err)) from None
    started = time.perf_counter()
    library = load_library(args.library)
    try:
        structure = design(spec, args.seed, library, mats=not args.no_mat)
    except UnmeetableSpec as err:
        raise InputError(str(err)) from None
    seconds = time.perf_counter() - started
    report, shares = member_load_shares(structure)
    path = _write(structure, args.output, MeshStyle())
    made = structure.metadata["design"]
    summary = {
        "file": str(path), "spec": made["spec"], "seed": args.seed, "dimensions": list(dimensions(structure)),
        "vertices": structure.n_vertices, "members": structure.n_edges, "stands": report.stands,
        "peak_load_share": float(np.nanmax(shares)) if structure.n_edges else 0.0, "answers": made["answers"],
        "on_mat": made["on_mat"], "above_ground": made["above_ground"], "seconds": round(seconds, 3),
    }  # fmt: skip
    if args.json:
        print(json.dumps(summary))
    else:
        print(
            f"{path}: {spec}: {structure.n_vertices} vertices, {structure.n_edges} members, peak load "
            f"{summary['peak_load_share']:.0%} of the break force, stands (static analysis)"
            + ("; a {}x{} tower on a floor mat filling the footprint".format(*made["above_ground"]) if made["on_mat"] else "")
            + "; "
            + (f"one of {made['answers']} answers (--seed picks)" if made["answers"] > 1 else "the only answer")
            + f", {seconds:.2f} s"
        )
    return EXIT_OK


def cmd_design_library(args: argparse.Namespace) -> int:
    """build the library 'structgen design' draws from

    Search --ncas NCAs by MAP-Elites over footprint width, depth and height (a pyribs archive per NCA family, the
    objective the safety margin below the break force), growing each in the boxes of --specs-each random specs; keep
    the --keep NCAs that answer the most specs and list every spec each meets; then teach NCAs to grow tilings of
    pyramids (wider than one pyramid of their height can be), and designs cut to narrow boxes (taller than a pyramid
    of their width can be), and add every spec they meet. Then every answer the static analysis loads above 70 % of
    the break force is simulated for PyBullet's first 0.3 s and dropped if a joint would break (--workers
    processes). Then, for the specs still unmet, designs are searched in each one's own box, taught, added and
    screened alike; last, answers of smaller footprints are set on a floor mat that fills an unmet spec's footprint
    (the mat lies on the ground and carries only itself), taught, added and screened alike. The same options give
    the same library on the same machine, whatever --workers. About half an hour per thousand NCAs on one core, ten
    minutes for the tilings, about an hour for the narrow designs (half of it their rules per in-degree class, from
    five levels), about an hour on 2 cores for the screen, 45 minutes on 2 cores for the designs in their own boxes
    and a few minutes for the mats.
    """
    from structgen.domains.structures.design import build_library

    output = Path(args.output)
    if output.suffix != ".npz":
        raise InputError(f"{output}: a design library is a .npz file")
    if output.exists() and not args.overwrite:
        raise InputError(f"{output}: exists (--overwrite replaces it)")
    started = time.perf_counter()
    library = build_library(args.ncas, args.seed, specs_each=args.specs_each, keep=args.keep, workers=args.workers,
                            progress=True)  # fmt: skip
    library.save(output)
    print(f"{output}: {len(library.families)} NCAs answer {len(library.specs())} specs ({len(library.answers)} answers) "
          f"after searching {args.ncas} NCAs in {time.perf_counter() - started:.0f} s")  # fmt: skip
    return EXIT_OK


def _footprint(text: str) -> tuple[int, int]:
    parts = text.lower().split("x")
    try:
        width, depth = (int(part) for part in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give the footprint as WxD, e.g. 5x7") from None
    if not (1 <= width <= 10_000 and 1 <= depth <= 10_000):
        raise argparse.ArgumentTypeError(f"{text!r}: width and depth must be whole numbers from 1 to 10,000")
    return width, depth


def _seed_vertex(text: str) -> int | str:
    if text == "top":
        return text
    try:
        return whole_number(0, 2**31 - 1)(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"{text!r}: give 'top' or a vertex index (0, 1, ...)") from None


def cmd_teach(args: argparse.Namespace) -> int:
    """fit NCA weights that grow a given structure

    Fit the paper's local NCA (52 inputs, a hidden ReLU layer, 26 outputs) so that it grows FILE from one of its
    vertices, then stops: vertices appear in order of their distance from the seed, each step one layer. Refused,
    naming two vertices, when the NCA's shared rule cannot do it (two vertices see the same neighbourhood but must
    act differently). Prints the 'structgen grow' command that grows it.
    """
    from structgen.domains.structures.teach import teach
    from structgen.nca import save_weights

    if args.output.suffix.lower() not in (".npy", ".json"):
        raise InputError(f"{args.output}: weights are written as .npy or .json, not {args.output.suffix or 'no suffix'!r}")
    target = _load_structure(args.file)
    started = time.perf_counter()
    try:
        taught = teach(target, seed_vertex=args.seed_vertex, hidden=args.hidden, cutoff=args.cutoff, margin=args.margin)
    except ValueError as err:  # TeachError, or an NCA setting out of range
        raise InputError(f"{args.file}: {err}") from None
    path = save_weights(args.output, taught.weights)
    print(
        f"{path}: taught {taught.n_rules} rules in {time.perf_counter() - started:.1f} s (every output at least "
        f"{taught.margin:.2f} logits from its threshold); the weights grow {_describe(taught.grown)} in "
        f"{taught.steps} steps, then nothing changes"
    )
    print(f"grow it: {grow_command(path, taught.config, 'grown.json')}")
    return EXIT_OK


TALL_OPTIONS = {
    "levels": "search.levels",
    "beam": "search.beam",
    "candidates": "search.candidates",
    "max_vertices": "search.max_vertices",
    "footprint": "search.footprint",
    "refine": "search.refine",
}


def cmd_tall(args: argparse.Namespace) -> int:
    """find the tallest tower an NCA can grow that stands, and teach it

    Search level-by-level designs (one rule per level from a top vertex) for the tallest whose levels the NCA's
    shared local rule can tell apart: a beam search from the top ranked by static joint load, the best of each
    height simulated for the physics' first 0.3 s (the lowest peak force wins), then every change of two levels'
    rules of the tallest tried (and of the next lower while none above holds). Each height's design is taught to the
    paper's 52-60-26 network. The run folder holds config.toml (every setting), designs.csv (a row per height),
    tall_<levels>.npy (weights), tall_<levels>.json (what they grow), tallest.png, and checkpoint.json (after each
    height): `structgen resume DIR` or the same command goes on after an interruption. The defaults reach eight
    levels in about 8 minutes on 2 cores.
    """
    from structgen.domains.structures.tall import find_tallest
    from structgen.domains.structures.tall_settings import TallSettings

    settings = settings_from_args({"search": TallSettings()}, args, TALL_OPTIONS)["search"]
    run_dir = Path(args.run_dir or f"runs/tall-{settings.levels}")
    say = _printer()
    result = find_tallest(settings, run_dir, workers=args.workers, progress=True, log=say, overwrite=args.overwrite)
    return _report_tall(result, run_dir)


def _printer() -> Any:
    return lambda line: print(line, flush=True)


def resume_tall(run_dir: Path, workers: int | None) -> int:
    """``structgen resume`` on a tall search folder: the search goes on with the settings it was started with."""
    from structgen.domains.structures.tall import resume_search

    return _report_tall(resume_search(run_dir, workers=workers, progress=True, log=_printer()), run_dir)


def _report_tall(result: Any, run_dir: Path) -> int:
    from structgen.domains.structures.tall import TRANSIENT_WINDOW

    limits = result.settings.physics
    seconds = sum(result.teach_seconds.values())
    print(f"{run_dir}: taught {len(result.taught)} heights ({seconds:.1f} s); table: {run_dir / 'designs.csv'}")
    if result.tallest_holding != result.tallest:
        print(
            f"the {result.tallest}-level design peaks at {result.designs[result.tallest].peak:.1f} N in the first "
            f"{TRANSIENT_WINDOW:g} s, over the {limits.break_force:g} N break force: it breaks"
        )
    levels = result.tallest_holding
    if levels is None:
        print("no height holds in the transient")
        return EXIT_FAILURE
    grown = result.taught[levels].grown
    print(
        f"the tallest that holds: {levels} levels, {run_dir / f'tall_{levels}.npy'}, growing {_describe(grown)} "
        f"(peak {result.designs[levels].peak:.1f} N); picture: {run_dir / 'tallest.png'}"
    )
    print(f"grow it: {grow_command(run_dir / f'tall_{levels}.npy', result.taught[levels].config, 'tall.json')}")
    from physics import PhysicsConfig
    from structgen.config import flatten, to_table

    # The check command carries the search's own physics (where it differs from the default) and the room it needs.
    changed = {
        key: value for key, value in flatten(to_table(limits)).items() if flatten(to_table(PhysicsConfig())).get(key) != value
    }
    changed.update(limits.room_for(grown.n_vertices, grown.n_edges))
    print(
        f"its {limits.horizon:g} s verdict (minutes): structgen evaluate {run_dir / f'tall_{levels}.json'}"
        + "".join(f" --set {name}={value}" for name, value in changed.items())
    )
    return EXIT_OK


def cmd_experiment(args: argparse.Namespace) -> int:
    """one of the stable-structures paper's four experiments at its settings: runs per seed, then the table

    Run configs/paper_NAME.toml once per seed (OUT_DIR/seed-S; a folder there is resumed, or kept if it got far
    enough), several runs at a time, keeping each run's best structure at the paper's spawn numbers
    (OUT_DIR/seed-S-spawns/), then write OUT_DIR/table.json and OUT_DIR/table.md beside the paper's numbers: the
    first structure standing whole, the tallest standing by spawns 5,800, 6,811, 7,480 and 28,577, the best score,
    and the paper's Table 1 (time per generation by the population's mean integrity) measured here.
    """
    from structgen.domains.structures.experiment import run_experiment, table_markdown

    report = run_experiment(
        args.name, args.out_dir, config=args.config, seeds=args.seeds, parallel=args.parallel, workers=args.workers,
        spawns=args.spawns, progress=not args.json, results=args.results, table_only=args.table_only,
        optimizer=args.optimizer,
    )  # fmt: skip
    return print_table(report, args, table_markdown)


def cmd_figure(args: argparse.Namespace) -> int:
    """the paper's figures from an experiment: each run's best structure at the paper's spawn numbers

    Lay out the pictures an experiment kept (OUT_DIR/seed-S-spawns/spawn-N/structure.png) in one PNG, a row per seed
    and a column per spawn number, as the paper's figures 4 to 9 show its structures.
    """
    from structgen.domains.structures.experiment import figure

    print(figure(args.out_dir, args.output))
    return EXIT_OK


def _mesh_options(title: str) -> Adder:
    return group(
        title,
        settings(MeshStyle, [name for name in MESH_OPTIONS]),
        flag("--solid", "union every sphere and cylinder into one closed, watertight shell (for 3D printing; slower)"),
        flag(
            "--stress",
            "colour each member by its static load as a share of the joint break force (GLB, OBJ, PLY; a "
            "GLB's metadata holds the colour key): pale none, orange half, dark red the break force, darker over it, "
            "purple no static answer; the default physics, a run's own for a run's elite",
        ),
    )


def _nca_options(title: str) -> Adder:
    return group(
        title,
        settings(NCAConfig, ("iterations", "cutoff", "hidden")),
        option("--no-build-down", dest="build_down", action="store_const", const=False,
               help="never grow below the seed's level (the paper's special rule)"),
        settings(NCAConfig, ("max_vertices", "max_extent")),
    )  # fmt: skip


def _describe_preset(name: str, preset: PhysicsConfig) -> str:
    stop = f"stop when settled, at most {preset.horizon:g} s" if preset.early_stop else f"{preset.horizon:g} s"
    return f"{name}: 1/{1 / preset.timestep:.0f} s steps, {preset.solver_iterations} solver iterations, {stop}"


_DEFAULT_PRESET = next(name for name, preset in PhysicsConfig.presets().items() if preset == PhysicsConfig())
_PHYSICS = group(
    "physics",
    option("--preset", choices=list(PhysicsConfig.presets()), help="; ".join(_describe_preset(name, preset) for name, preset
           in PhysicsConfig.presets().items()) + f" (default {_DEFAULT_PRESET}; --set physics.preset=NAME is the same)"),
    set_option("the physics (physics.*)", "break_force=60 or physics.horizon=10"),
    one_of(flag("--statics", "predict with the static frame solve (milliseconds, no size cap) instead of simulating"),
           real("--transient", 0, 3600, help="simulate only the first SECONDS (0.3 covers the spawn transient) with joints "
                "that hold, and rate the largest joint force against the break force: integrity becomes min(1, break "
                "force / peak force)", above=True, metavar="SECONDS")),
)  # fmt: skip
_FILE = option("file", metavar="FILE", help="structure JSON file")


class StructureCommands(DomainCommands):
    renamed = {"check": "evaluate", "render": "show"}  # until 0.5
    # In the top-level form; `structgen structures VERB` is the same verb.
    examples = {"export": ["structgen structures export runs/qd best.glb", "structgen structures export tower.json tower.stl"]}
    # Examples in the top-level form; `structgen structures VERB` is the same verb.
    adders = verbs(
        verb("experiment", cmd_experiment, option("name", choices=list(EXPERIMENTS), help="the experiment"),
             seed_run_options(config_default=None, config_help="default configs/paper_NAME.toml", seeds=[0, 1, 2],
                              seeds_help="default 0 1 2"),
             number("--spawns", 1, 10**8, help="networks each run evaluates (default the paper's: 28,577 for baseline and "
                    "average-height, 5,800 for cutoff, 6,811 for no-build-down); the run goes to the end of the generation "
                    "holding spawn N"),
             workers("evaluation processes of each run, 0 for the run's own process (default 1: on a few cores, runs side "
                     "by side use them best); results do not depend on it", default=1),
             option("--results", metavar="STEM", help="also put the table into STEM.json and STEM.md, the tables of all "
                    "four experiments (the project keeps them in docs/results/structures-paper-table)"),
             flag("--table-only", "run nothing: write the table from the seeds' runs as they stand (an unfinished run with "
                  "the spawns it reached; resume it later without this option)"),
             examples=["structgen structures experiment cutoff runs/cutoff --seeds 0 1 2",
                       "structgen structures experiment baseline runs/baseline --table-only"]),
        verb("figure", cmd_figure, option("out_dir", metavar="OUT_DIR", help="an experiment's folder"),
             output("OUT.png", "where to write the figure (default OUT_DIR/figure.png)", required=False),
             examples=["structgen structures figure runs/cutoff -o cutoff.png"]),
        verb("grow", cmd_grow,
             one_of(seed("random NCA drawn with this seed"), nca_weights(),
                    option("--run", metavar="RUN_DIR", help="an evolution run's NCA (its settings, then any NCA options "
                           "given here, e.g. more --iterations)")),
             option("--elite", default="best", metavar="best|index:I", help="with --run: which NCA"),
             output(help="output file; format from the suffix"),
             option("--frames", type=_frames_folder, metavar="DIR", help="also draw the structure after every growth "
                    "step, from the lone seed on, as DIR/step_000.png, ..."),
             option("--gif", type=_gif_path, metavar="FILE.gif", help="also write the growth steps as an animated GIF"),
             _nca_options("NCA (defaults follow the paper)"),
             _mesh_options("mesh dimensions (mesh formats only; defaults match the physics model)"),
             set_option("the NCA (nca.*) and the mesh (mesh.*)", "nca.cutoff=0.6 or sphere_radius=0.2"),
             examples=["structgen grow --seed 1 -o tower.json", "structgen grow --run runs/qd -o best.glb --gif growth.gif"]),
        verb("evaluate", cmd_check, _FILE, json_flag("print the whole report as one JSON object"),
             flag("--strict", "exit with 1 unless it stands (a joint broke, or it never came to rest)"), _PHYSICS,
             examples=["structgen evaluate tower.json --preset fast", "structgen evaluate tower.json --statics --json"]),
        verb("show", cmd_render, _FILE, output("OUT.png", "image to write"), dpi(), _PHYSICS,
             flag("--stress", "draw each member in the colour of its static load as a share of the break force (the "
                  "static analysis of the intact structure, with these physics settings), with a colour bar"),
             flag("--peaks", "draw each member in the colour of the largest force either of its joints carried in the "
                  "simulation, as a share of the break force, with a colour bar: where PyBullet loads it (with "
                  "--transient 0.3, the spawn transient's peaks), which for tall frames is not where the static "
                  "analysis does"),
             examples=["structgen show tower.json -o tower.png --preset fast",
                       "structgen show tower.json -o stress.png --statics --stress",
                       "structgen show nine.json -o peaks.png --transient 0.1 --peaks --set max_joints=5000"]),
        verb("teach", cmd_teach, option("file", metavar="FILE", help="structure JSON file to grow"),
             output("OUT.npy", "weights to write (.npy or .json)"),
             option("--seed-vertex", type=_seed_vertex, default="top", metavar="top|INDEX", help="the vertex growth starts "
                    "from: 'top' (the single highest vertex, the default) or its index in FILE"),
             settings(NCAConfig, ("hidden", "cutoff"), defaults={"hidden": 60, "cutoff": 0.5}),
             real("--margin", 0, 100, 1.0, "how far (in logits) every output must clear its threshold", above=True),
             examples=["structgen teach tower.json -o tower_nca.npy"]),
        verb("regrow", cmd_regrow, _FILE, nca_weights(),
             real("--damage", 0, 1, 0.25, "share of the members to cut out", above=True),
             option("--cut", choices=CUTS, default="mid", help="mid: the members nearest the middle height (one cut "
                    "through it); random: drawn at random with --seed"),
             seed("the random cut's seed"), output(help="the regrown structure (json, glb, obj, stl, ply)", required=False),
             option("--picture", type=png_output_path, metavar="OUT.png", help="draw it grown, damaged and regrown"),
             flag("--transient", "also hold the regrown structure to PyBullet's first 0.3 s of the faithful preset "
                  "(seconds for a tower): the static analysis lets some regrown towers near the break force stand "
                  "that PyBullet breaks"),
             json_flag(), _nca_options("NCA (defaults: the settings FILE was grown with)"),
             examples=["structgen regrow regrows.json --weights docs/tall_regrow_8.npy --damage 0.25 --cut mid "
                       "--picture regrown.png"]),
        verb("design", cmd_design,
             option("--footprint", type=_footprint, required=True, metavar="WxD", help="cells on the ground: width "
                    "(x) by depth (y)"),
             number("--height", 1, 10_000, help="levels (the z extent is one less)", required=True),
             number("--max-members", 0, 10**9, help="at most this many edges (default: any)"),
             seed("which of the spec's answers: different seeds, different designs where the library has several"),
             flag("--no-mat", "refuse answers that are a smaller tower on a floor mat filling the footprint (some specs "
                  "have no other)"),
             option("--library", type=Path, metavar="FILE.npz", help="a design library (default: the one that ships, "
                    "built by structgen design-library)"),
             output(help="the design (json, glb, obj, stl, ply)"), json_flag(),
             examples=["structgen design --footprint 5x7 --height 4 -o tower.json",
                       "structgen design --footprint 9x9 --height 6 --max-members 400 --seed 2 -o tower.glb"]),
        verb("design-library", cmd_design_library, output("FILE.npz", "the library to write"),
             number("--ncas", 1, 10**7, 2_000, "NCAs to search"), seed("the search's seed"),
             number("--specs-each", 1, 528, 48, "random specs each NCA is grown for during the search"),
             number("--keep", 1, 10_000, 64, "NCAs kept in the library"),
             workers("processes for the last step's simulations, 0 for this one; the library does not depend on it "
                     "(default 2)", default=2),
             overwrite("the library file if it exists"),
             examples=["structgen design-library -o my_library.npz --ncas 500"]),
        verb("tall", cmd_tall,
             option("--run-dir", type=output_folder, metavar="DIR", help="run folder: new, empty, or one a search with the same "
                    "settings "
                    "started (it resumes; with more --levels it goes on from there); default runs/tall-<levels>"),
             overwrite(), settings(TallSettings, ("levels", "beam", "candidates", "max_vertices", "footprint")),
             option("--refine", action=argparse.BooleanOptionalAction, help="try every change of two levels' rules of the "
                    "tallest design (default on, a few minutes at eight levels; search.refine)"),
             workers("processes for the simulations, 0 for this one; results do not depend on it (default 2)", default=2),
             set_option("the search (search.*, the physics in search.physics.*)", "break_force=60 or search.beam=10"),
             examples=["structgen tall --run-dir runs/tall --levels 5 --workers 2",
                       "structgen tall --run-dir runs/tall-f5 --levels 7 --footprint 5"]),
    )  # fmt: skip

    def describe_path(self, path: Path) -> tuple[dict[str, Any], str] | None:
        return describe_structure(path)

    def describe_run(self, kind: str, run_dir: Path) -> tuple[dict[str, Any], str]:
        if kind != "tall":
            return super().describe_run(kind, run_dir)
        from structgen.domains.structures.tall import describe_search, search_summary

        summary = search_summary(run_dir)
        return summary, describe_search(summary)

    def resume_run(self, kind: str, run_dir: Path, args: argparse.Namespace) -> int:
        if kind != "tall":
            return super().resume_run(kind, run_dir, args)
        if args.generations is not None or args.cluster is not None:
            raise InputError(f"{run_dir}: a tall search has no generations and runs on this machine; give --workers only")
        return resume_tall(run_dir, args.workers)

    def report_view(self, problem: Any, genome: Any) -> dict[str, Any]:
        from structgen.domains.structures.view import structure_view

        return structure_view(problem.structure_of(genome), problem.settings.physics)

    def report_file(self, path: Path) -> dict[str, Any] | None:
        """A structure file, or what ``structgen evaluate --json`` printed (its structure drawn, its numbers beside)."""
        from evolution.files import parse_json, read_text
        from structgen.domains.structures.view import structure_view

        if path.is_dir():
            return None
        data = parse_json(read_text(path, 1 << 28, what="a JSON file"), str(path))
        if isinstance(data, dict) and "method" in data and isinstance(data.get("file"), str):
            checked = {key: data.get(key) for key in ("method", "integrity", "height", "complexity", "score", "stands")}
            view = structure_view(_load_structure(data["file"]))
            return {**view, "fields": {**view["fields"], **{f"check: {k}": v for k, v in checked.items()}}}
        return structure_view(_load_structure(path))

    def add_export_options(self, parser: argparse.ArgumentParser) -> None:
        _mesh_options("structures: mesh dimensions (mesh formats only; defaults match the physics model)")(parser)

    def export_file(self, source: Path, output: Path, args: argparse.Namespace) -> str:
        structure = _load_structure(source)
        path = _write(structure, output, _mesh_style(args), args.solid, _stress_physics(args))
        return f"{path}: {_describe(structure)}"

    def export_elite(self, problem: Any, genome: Any, output: Path, args: argparse.Namespace, origin: Mapping[str, str]) -> str:
        structure = problem.structure_of(genome).with_metadata(**origin)
        path = _write(structure, output, _mesh_style(args), args.solid, _stress_physics(args, problem.settings.physics))
        return f"{path}: {_describe(structure)}"


COMMANDS = StructureCommands()
