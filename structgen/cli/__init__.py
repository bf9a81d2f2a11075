"""The ``structgen`` command line: generic verbs, and each registered domain's own verbs under its name.

- ``structgen list domains|optimizers``, ``structgen evolve``, ``structgen resume``, ``structgen export`` and
  ``structgen info`` work for every registered domain (built in or installed as a plugin) and know none of them by
  name.
- ``structgen <group> <verb>``: a domain's own verbs, added by the domain
  (:class:`structgen.registry.commands.DomainCommands`), plus ``evolve``, ``export`` and ``info`` limited to that
  domain. Verbs a domain lists as shortcuts are also top-level verbs.

Results go to stdout, logs to stderr. Exit codes: 0 success, 1 runtime failure, 2 bad input or usage (a one-line
message naming the file and the problem; ``--verbose`` adds the traceback). Nothing is written when input is bad.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from structgen import __version__, domains
from structgen.registry.commands import (
    EXIT_BAD_INPUT,
    EXIT_FAILURE,
    EXIT_INTERRUPTED,
    EXIT_OK,
    InputError,
    Parser,
    Verb,
    check_outputs,
    flag,
    json_flag,
    number,
    option,
    output,
    output_folder,
    output_path,
    renamed_verb_note,
    seed,
    set_option,
    verb,
    verbs,
)
from structgen.runs.report import ELITES

log = logging.getLogger("structgen")

GENERIC_VERBS = ("list", "evolve", "resume", "export", "info", "compare", "report")
# Bounds of the run options given by name (RunSettings checks the same settings however they are given).
MAX_GENERATIONS, MAX_WORKERS = 10**9, 1024


# -- generic verbs --------------------------------------------------------------------------------------------------------
def cmd_list(args: argparse.Namespace) -> int:
    """list the registered domains or optimizers

    One line for each domain or optimizer.
    """
    if args.what == "domains":
        rows = [{"id": d.id, "group": d.group_name, "aliases": list(d.aliases), "summary": d.summary} for d in domains.specs()]
        key = "id"
    else:
        from evolution import OPTIMIZERS
        from structgen.config import to_table

        rows = [
            {"name": name, "summary": spec.summary, "settings": to_table(spec.settings())} for name, spec in OPTIMIZERS.items()
        ]
        key = "name"
    if args.json:
        print(json.dumps(rows))
    else:
        width = max(len(row[key]) for row in rows)
        for row in rows:
            print(f"{row[key]:<{width}}  {row['summary']}")
    return EXIT_OK


def _report_run(folder: Any, state: Any) -> None:
    best = state.best
    print(f"{folder.path}: {state.generation} generations, {state.evaluations} evaluations, {state.elapsed:.1f} s")
    if best is not None:
        details = ", ".join(f"{k} {v:g}" for k, v in best.fields.items())
        print(f"best: objective {best.objective:g} (generation {best.generation}){'; ' + details if details else ''}")


def cmd_evolve(args: argparse.Namespace) -> int:
    """run an evolution (with no arguments: the main job)

    Evolve {which} with the configuration in CONFIG (TOML with [run], [problem] and [optimizer] tables), or, without
    CONFIG, the domain's main job (a run of a few minutes).

    Writes a run folder: config.toml, manifest.json, checkpoint.pkl, metrics.jsonl, best/, plots, and the archive for
    quality diversity.

    Ctrl-C finishes the generation, checkpoints and exits (130); `structgen resume` continues.
    """
    from evolution import graceful_interrupt
    from structgen.runs import evolve
    from structgen.runs.experiment import load_experiment

    changes = {"generations": args.generations, "seed": args.seed, "workers": args.workers, "cluster": args.cluster}
    experiment = load_experiment(
        args.config, domain=args.domain, overrides=args.set, optimizer=args.optimizer, run_changes=changes
    )
    if args.print_config:
        print(experiment.to_toml(), end="")
        return EXIT_OK
    with graceful_interrupt() as stop:
        folder, state = evolve(experiment, args.run_dir, overwrite=args.overwrite, stop_requested=stop)
        _report_run(folder, state)
        return EXIT_INTERRUPTED if stop() else EXIT_OK


def cmd_resume(args: argparse.Namespace) -> int:
    """continue a run from its last checkpoint

    Continue the run in RUN_DIR from its last checkpoint, reading only its config.toml; the result is the same as if
    it had never stopped. A domain's own kind of run (a tall search) is continued by its domain, with the settings
    it was started with.
    """
    from evolution import graceful_interrupt
    from structgen.runs import other_run_kind, resume

    other = other_run_kind(args.run_dir)
    if other is not None:  # a domain's own kind of run (a search): the domain resumes it
        domain, kind = other
        return _hooks(domains.spec(domain), Path(args.run_dir)).resume_run(kind, Path(args.run_dir), args)
    with graceful_interrupt() as stop:
        folder, state = resume(
            args.run_dir, generations=args.generations, workers=args.workers, cluster=args.cluster, stop_requested=stop
        )
        _report_run(folder, state)
        return EXIT_INTERRUPTED if stop() else EXIT_OK


def cmd_export(args: argparse.Namespace) -> int:
    """write a file, or an elite of a run, in another format

    Write SOURCE to OUT in the format OUT's suffix names. SOURCE is a run folder (its best candidate, or an archive
    elite, made again from its genome) or a file of {which}.
    """
    output = args.output_option or args.output
    if not output:
        raise InputError("export needs an output file: structgen export SOURCE OUT (or -o OUT)")
    if args.output_option and args.output:
        raise InputError("give the output file once, either as OUT or as -o OUT")
    source = Path(args.source)
    if source.is_dir():
        line = _export_elite(source, Path(output), args)
    else:
        if args.elite != "best":
            raise InputError("--elite only applies to run folders")
        domain = domains.spec(args.domain or domains.DEFAULT_DOMAIN)
        line = _hooks(domain, source).export_file(source, Path(output), args)
    print(line)
    return EXIT_OK


def cmd_info(args: argparse.Namespace) -> int:
    """summarise a run folder, or a file

    Summarise a run folder of any domain (what the run is, how far it got, its best candidate and archive; a search
    or an agent training, as its domain tells it) or a file of {which} (a structure: counts, height, bounding box,
    components).
    """
    from evolution import RunFolder

    path = Path(args.path)
    domain = domains.spec(args.domain or domains.DEFAULT_DOMAIN)
    if path.is_dir() and (path / RunFolder.MANIFEST).is_file():
        from structgen.runs import describe_folder

        described = describe_folder(path)
    else:  # a file of the domain's, or a folder of its own (an old search folder): the domain knows it
        hooks = domain.command_hooks()
        described = hooks.describe_path(path) if hooks is not None else None
        if described is None:
            if path.is_dir():
                raise InputError(f"{path}: no run folder (no manifest.json), nor a folder the {domain.id} domain knows")
            raise InputError(f"{path}: not a file the {domain.id} domain describes (--domain names another)")
    summary, text = described
    print(json.dumps(summary) if args.json else text)
    return EXIT_OK


def _hooks(domain: domains.DomainSpec, source: Path) -> Any:
    hooks = domain.command_hooks()
    if hooks is None:
        raise InputError(f"{source}: the {domain.id} domain has nothing to export")
    return hooks


def _export_elite(run_dir: Path, output: Path, args: argparse.Namespace) -> str:
    from structgen.runs import elite_genome, open_run

    folder, experiment = open_run(run_dir)
    if args.domain and domains.spec(args.domain).id != experiment.domain:
        raise InputError(f"{run_dir}: a run of the {experiment.domain} domain, not of {args.domain}")
    hooks = _hooks(experiment.spec, run_dir)
    problem = experiment.make_problem()
    try:
        genome = elite_genome(folder, problem, args.elite)
        return hooks.export_elite(problem, genome, output, args, {"run": str(run_dir), "elite": args.elite})
    finally:
        problem.close()


def cmd_compare(args: argparse.Namespace) -> int:
    """compare runs: a table of their results and a plot of their progress

    Print a table of each run's generations, evaluations, best objective and (quality diversity) QD score and
    coverage, and draw their best objective (and QD score and coverage, when every run has an archive) over
    generations in one picture.
    """
    from evolution import atomic_write
    from evolution.plots import compare_figure, figure_png
    from structgen.runs import check_numbers, open_run, summary_of

    output = Path(args.output)
    runs, table = {}, []
    for run_dir in args.runs:
        folder, experiment = open_run(run_dir)
        rows = folder.metrics()
        if not rows:
            raise InputError(f"{run_dir}: this run has no finished generation to compare")
        check_numbers(folder / "metrics.jsonl", rows, ("generation", "evaluations", "best_objective"))
        label = folder.path.name
        while label in runs:  # two folders of the same name in different places
            label += "'"
        runs[label] = rows
        summary = summary_of(folder, experiment, rows)
        archive = summary.get("archive", {})
        table.append(
            {
                **{key: summary[key] for key in ("run", "domain", "optimizer", "generations", "evaluations")},
                "best_objective": rows[-1]["best_objective"],  # the metrics' own: best.json lags between checkpoints
                "qd_score": archive.get("qd_score"),
                "coverage": archive.get("coverage"),
            }
        )
    lines = ["| run | domain | optimizer | generations | evaluations | best objective | QD score | coverage |"]
    lines.append("|---|---|---|---:|---:|---:|---:|---:|")
    for row in table:
        qd = "-" if not isinstance(row["qd_score"], (int, float)) else f"{row['qd_score']:.4g}"
        coverage = "-" if not isinstance(row["coverage"], (int, float)) else f"{row['coverage']:.1%}"
        lines.append(
            f"| {row['run']} | {row['domain']} | {row['optimizer']} | {row['generations']} | {row['evaluations']:,} | "
            f"{row['best_objective']:.4g} | {qd} | {coverage} |"
        )
    # Everything is read and checked before anything is written: a refusal leaves no file behind.
    atomic_write(output, figure_png(compare_figure(runs)))
    if args.html is not None:
        from structgen.runs.report import compare_page, write_page

        log.info("wrote %s", write_page(compare_page(runs, table), args.html))
    print(json.dumps(table) if args.json else "\n".join(lines))
    log.info("wrote %s", output)
    return EXIT_OK


def cmd_report(args: argparse.Namespace) -> int:
    """write a report: one HTML page, opened offline in any browser, of a run or of a file

    For a run folder of any domain: its settings and timing, its progress (best objective; QD score and coverage for
    quality diversity), its archive as a heatmap where a click on a cell shows its elite, and its best candidate, each
    drawn as its domain draws it (a structure in 3D to turn, members coloured by load; a layout, a game or a world as
    its picture). For a file of a domain (a structure, or what `structgen evaluate --json` printed): its view
    alone. Nothing is written when the input is bad.
    """
    from evolution import RunFolder
    from structgen.runs.report import item_page, run_page, write_page

    source, started = Path(args.source), time.perf_counter()
    if source.is_dir():
        if not (source / RunFolder.MANIFEST).is_file():
            raise InputError(f"{source}: no run folder (no manifest.json)")
        page = run_page(source, elites=args.elites, progress=sys.stderr.isatty())
    elif source.is_file():
        page = item_page(source, domains.spec(args.domain or domains.DEFAULT_DOMAIN))
    else:
        raise InputError(f"{source}: no such file or folder")
    path = write_page(page, args.output)
    print(f"{path}: {len(page.encode()) / 1e6:.1f} MB in {time.perf_counter() - started:.1f} s")
    return EXIT_OK


# -- parser -------------------------------------------------------------------------------------------------------------
class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions keep their line breaks (lists of domains read better that way)."""


def _generic_verbs(domain: domains.DomainSpec | None, exporters: list[tuple[domains.DomainSpec, Any]]) -> dict[str, Verb]:
    """The verbs every domain has, for ``domain``'s group (its id set) or, with None, at the top (``--domain``
    chooses)."""
    which = domain.id if domain else f"a domain's (--domain; default {domains.DEFAULT_DOMAIN})"
    me = f"structgen {domain.group_name}" if domain else "structgen"
    choose = (
        []
        if domain
        else [option("--domain", metavar="ID", help=f"the domain FILE belongs to (default {domains.DEFAULT_DOMAIN})")]
    )
    return verbs(
        verb("list", cmd_list, option("what", choices=("domains", "optimizers"), help="what to list"),
             json_flag("print a JSON list with more about each"),
             examples=["structgen list domains", "structgen list optimizers --json"]),
        verb("evolve", cmd_evolve, option("config", nargs="?", metavar="CONFIG.toml", help="run configuration (default: "
             "the main job)"),
             *[] if domain else [option("--domain", metavar="ID", help="the domain to evolve (sets problem.name; "
                                        "`structgen list domains` lists them); without CONFIG, its main job")],
             option("--optimizer", metavar="NAME", help="ga, cma_es, map_elites, cma_mae or random (sets optimizer.name)"),
             number("--generations", 1, MAX_GENERATIONS, help="generations in total (sets run.generations)"),
             seed("the run's seed (sets run.seed)", default=None),
             number("--workers", 0, MAX_WORKERS, help="local evaluation processes, 0 for none (run.workers)"),
             option("--cluster", metavar="ADDRESS", help="evaluate on the Dask scheduler at ADDRESS (run.cluster)"),
             option("--run-dir", type=output_folder, metavar="DIR",
                    help="run folder to create (default runs/<domain>-<optimizer>-s<seed>-<time>)"),
             flag("--overwrite", "replace RUN_DIR if it is already a run folder"),
             set_option("the run, the problem or the optimizer", "optimizer.population=100 or run.seed=3 (--print-config "
                        "shows every setting of the chosen domain)"),
             flag("--print-config", "print the resolved configuration (every setting, as a run would record it) and exit "
                  "without running"),
             text={"which": domain.id if domain else f"the domain CONFIG names ({domains.DEFAULT_DOMAIN} if none)"},
             examples=[f"{me} evolve", f"{me} evolve --generations 5 --seed 1"] if domain else [
                 "structgen evolve", "structgen evolve configs/paper_cutoff.toml --workers 2 --run-dir runs/cutoff",
                 f"structgen evolve --domain {domains.DEFAULT_DOMAIN} --generations 5 --set optimizer.population=20"]),
        verb("resume", cmd_resume, option("run_dir", metavar="RUN_DIR", help="run folder"),
             number("--generations", 1, MAX_GENERATIONS, help="run up to N generations in total (default: as configured)"),
             number("--workers", 0, MAX_WORKERS, help="local evaluation processes this time (results do not change)"),
             option("--cluster", metavar="ADDRESS", help="evaluate on this Dask scheduler this time"),
             examples=["structgen resume runs/qd", "structgen resume runs/qd --generations 200 --workers 2"]),
        verb("compare", cmd_compare,
             option("runs", nargs="+", metavar="RUN_DIR", help="run folders, of any domain and optimiser"),
             output("OUT.png", "picture to write (default compare.png)", required=False, default="compare.png"),
             option("--html", type=output_path, metavar="OUT.html", help="also write the table and the curves as one HTML "
                    "page to open in a browser"),
             json_flag("print the table as a JSON list"),
             examples=["structgen compare runs/ga runs/qd -o compare.png", "structgen compare runs/* --json"]),
        verb("export", cmd_export, option("source", metavar="SOURCE", help="run folder or file"),
             option("output", nargs="?", type=output_path, metavar="OUT", help="output file (or use -o)"),
             # argparse fills both positionals at SOURCE, so an OUT typed after the options would be refused.
             lambda parser: parser.set_defaults(late_positional=("output", output_path)),
             option("-o", dest="output_option", type=output_path, metavar="OUT", help="output file"),
             option("--elite", default="best", metavar="best|index:I", help="for a run folder: the best candidate "
                    "(default) or the archive elite in cell I (see archive.csv)"),
             *choose, set_option("the export", "mesh.sphere_radius=0.2 for a structure"),
             lambda parser: _add_export_options(parser, exporters), text={"which": which},
             examples=[line for _, hooks in exporters for line in hooks.examples.get("export", ())] if domain else [
                 "structgen export runs/qd best.glb", "structgen export tower.json tower.stl",
                 "structgen export runs/qd -o elite.obj --elite index:12"]),
        verb("report", cmd_report, option("source", metavar="RUN_DIR|FILE", help="run folder, or a file"),
             output("OUT.html", "page to write (default report.html)", required=False, default="report.html"),
             *choose, number("--elites", 0, 10**6, ELITES, "archive elites given a view, the best first (the others show "
                             "their numbers only)"),
             examples=["structgen report runs/qd -o qd.html", "structgen report tower.json -o tower.html"]),
        verb("info", cmd_info, option("path", metavar="RUN_DIR|FILE", help="run folder, or a file"), *choose,
             json_flag("print one JSON object instead of lines to read"), text={"which": which},
             examples=[f"{me} info runs/{domain.group_name}"] if domain else ["structgen info runs/qd",
                                                                               "structgen info tower.json --json"]),
        **({"domain": domain.id} if domain else {}),
    )  # fmt: skip


def _add_export_options(parser: argparse.ArgumentParser, exporters: list[tuple[domains.DomainSpec, Any]]) -> None:
    for spec, hooks in exporters:
        try:
            hooks.add_export_options(parser)
        except argparse.ArgumentError as err:  # a plugin's option clashes with another domain's
            log.warning("export options of %s left out of this command: %s", spec.id, err)


def _domain_hooks() -> list[tuple[domains.DomainSpec, Any]]:
    """Every domain with its command hooks (None if it has none); a plugin whose hooks fail to load is left out."""
    found = []
    for spec in domains.specs():
        try:
            found.append((spec, spec.command_hooks()))
        except Exception as err:
            log.warning("commands of domain %s not loaded: %s: %s", spec.id, type(err).__name__, err)
    return found


def build_parser() -> argparse.ArgumentParser:
    hooked = _domain_hooks()
    listing = "\n".join(f"  {spec.group_name:<12} {spec.summary}" for spec, _ in hooked)
    parser = Parser(
        prog="structgen",
        formatter_class=_Formatter,
        description="Generate designs with neural cellular automata and other generators, judge them, and "
        f"evolve the generators.\n\nDomains (structgen <domain> --help for their verbs):\n{listing}",
    )
    parser.add_argument("--version", action="version", version=f"structgen {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log more, and show tracebacks on errors (anywhere)")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    exporters = [(spec, hooks) for spec, hooks in hooked if hooks is not None]
    for declared in _generic_verbs(None, exporters).values():
        declared(commands)

    taken = set(GENERIC_VERBS)
    for spec, hooks in hooked:
        if spec.group_name in taken:
            log.warning("domain %s: its command group %r is taken; reach it through the generic verbs", spec.id, spec.group_name)
            continue
        taken.add(spec.group_name)
        group = commands.add_parser(spec.group_name, help=f"the {spec.id} domain's verbs", description=spec.summary)
        subparsers = group.add_subparsers(dest="verb", metavar="VERB", required=True)
        generic = _generic_verbs(spec, [(spec, hooks)] if hooks is not None else [])
        generic["evolve"](subparsers)
        generic["info"](subparsers if hooks is None else hooks.verb_parsers(subparsers))
        if hooks is not None:
            generic["export"](subparsers)
            hooks.add_verbs(subparsers, spec)
    for spec, hooks in hooked:
        shortcuts = [name for name in spec.shortcuts if name not in taken]
        if hooks is not None and shortcuts:
            hooks.add_verbs(commands, spec, only=shortcuts)
            taken.update(shortcuts)
        for name in set(spec.shortcuts) - set(shortcuts):
            log.warning("domain %s: the top-level verb %r is taken; use structgen %s %s", spec.id, name, spec.group_name, name)
    return parser


def _unknown_options(unknown: list[str], args: argparse.Namespace, argv: list[str]) -> str:
    """argparse's complaint, with a hint when an unknown option could be a setting for --set."""
    if not (hasattr(args, "set") and unknown[0].startswith("--")):
        return f"unrecognized arguments: {' '.join(unknown)}"
    option = unknown[0]
    name, _, value = option[2:].partition("=")
    # argparse may have taken the option's value as a positional argument; the command line still has it.
    at = argv.index(option) if option in argv else -1
    if not value and 0 <= at < len(argv) - 1 and not argv[at + 1].startswith("-"):
        value, option = argv[at + 1], f"{option} {argv[at + 1]}"
    return f"unrecognized arguments: {option} (settings go through --set: --set {name.replace('-', '_')}={value or 'VALUE'})"


def _take_late_positional(args: argparse.Namespace, unknown: list[str]) -> list[str]:
    """What is left of ``unknown`` once a verb's optional last positional takes the one word left over after its
    options (``structgen export RUN --elite best OUT``), converted and checked by its type."""
    late = getattr(args, "late_positional", None)
    if late is None or len(unknown) != 1 or unknown[0].startswith("-"):
        return unknown
    dest, convert = late
    if getattr(args, dest) is not None:
        return unknown
    setattr(args, dest, convert(unknown[0]))
    return []


def _verbose_first(argv: list[str]) -> list[str]:
    """``argv`` with -v/--verbose moved to the front: it belongs to the top-level parser, and users type it after the
    command too (``structgen evolve CONFIG -v``). Nothing after ``--`` is touched."""
    end = argv.index("--") if "--" in argv else len(argv)
    flags = [word for word in argv[:end] if word in ("-v", "--verbose")]
    return flags + [word for word in argv[:end] if word not in ("-v", "--verbose")] + argv[end:]


def _report(message: str) -> None:
    # A message may quote input that is not valid text (half a surrogate pair): shown escaped, never a second error.
    encoding = getattr(sys.stderr, "encoding", None) or "utf-8"
    line = f"structgen: error: {message}".encode(encoding, errors="backslashreplace").decode(encoding)
    print(line, file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    # Our packages talk at INFO; third-party libraries (matplotlib, dask) only when something is wrong.
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s: %(message)s", stream=sys.stderr, force=True)
    parser = build_parser()
    argv = _verbose_first(list(sys.argv[1:] if argv is None else argv))
    args, unknown = parser.parse_known_args(argv)
    try:
        unknown = _take_late_positional(args, unknown)
    except argparse.ArgumentTypeError as err:
        _report(str(err))
        return EXIT_BAD_INPUT
    if unknown:
        _report(_unknown_options(unknown, args, argv))
        return EXIT_BAD_INPUT
    for name in ("structgen", "physics", "evolution"):
        logging.getLogger(name).setLevel(logging.DEBUG if args.verbose else logging.INFO)
    if note := renamed_verb_note(args, (args.command, getattr(args, "verb", None))):
        log.warning(note)
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        check_outputs(args)
        code = handler(args)
        sys.stdout.flush()  # a reader that stopped early shows here, not at interpreter exit
        return code
    except BrokenPipeError:
        # The reader of our output closed it (`structgen ... | head`): stop quietly, as Unix tools do on SIGPIPE.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 128 + 13
    except KeyboardInterrupt as err:
        _report(str(err) or "interrupted")  # a stopped seed run (RunStopped) says how to resume
        return EXIT_INTERRUPTED
    except Exception as err:
        code, message = _classify(err)
        _report(message)
        if args.verbose:
            traceback.print_exc()
        return code


def _classify(err: Exception) -> tuple[int, str]:
    """The exit code and one-line message for an error: the user's input (2), or a bug or broken environment (1)."""
    from evolution import InputFileError, RunFolderError
    from evolution.evaluators import UnreachableClusterError

    if isinstance(err, (InputError, InputFileError, RunFolderError, UnreachableClusterError, domains.UnknownDomainError)):
        return EXIT_BAD_INPUT, str(err)
    if isinstance(err, FileNotFoundError):
        return EXIT_BAD_INPUT, f"{err.filename}: no such file"
    if isinstance(err, (IsADirectoryError, PermissionError)):
        return EXIT_BAD_INPUT, f"{err.filename}: {err.strerror.lower()}"
    if isinstance(err, OSError) and err.filename is not None:  # a path the user gave: too long, a loop, not a folder
        from evolution.files import path_error

        named = path_error(err.filename, err)
        if isinstance(named, InputFileError):
            return EXIT_BAD_INPUT, str(named)
    return EXIT_FAILURE, f"{type(err).__name__}: {err}"


if __name__ == "__main__":
    sys.exit(main())
