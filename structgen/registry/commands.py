"""What the command line and the domains' own verbs share: the input error, exit codes, the ``--set`` option, and
the hooks through which a domain adds verbs and exports.

The command line (:mod:`structgen.cli`) knows no domain. A domain that wants verbs of its own names a
:class:`DomainCommands` in its :class:`~structgen.domains.DomainSpec`; the command line calls it to add
``structgen <group> <verb>`` (and the domain's top-level shortcuts), and to export the domain's files and run elites
through the generic ``structgen export``. This module stays light: it is imported to build every command line.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import math
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from structgen.config import Limit, limits_of
from structgen.errors import InputError

if TYPE_CHECKING:
    from structgen.registry import DomainSpec

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_FAILURE",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "MAX_SEED",
    "RENAMED_VERBS_GO_IN",
    "SHARED_VERBS",
    "DomainCommands",
    "VerbHelpFormatter",
    "InputError",
    "Parser",
    "seed_run_options",
    "add_set_option",
    "device_name",
    "examples_epilog",
    "finite_number",
    "output_path",
    "output_folder",
    "check_outputs",
    "OutputFile",
    "OutputFolder",
    "renamed_verb_note",
    "print_table",
    "settings_from_args",
    "verbs_wanted",
    "whole_number",
    "write_by_suffix",
    "add_setting_options",
    "given_settings",
    "limit_type",
    "Adder",
    "Verb",
    "device",
    "dpi",
    "nca_weights",
    "flag",
    "group",
    "json_flag",
    "number",
    "one_of",
    "option",
    "output",
    "overwrite",
    "real",
    "seed",
    "set_option",
    "settings",
    "verb",
    "verbs",
    "workers",
]

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2
#: Stopped by Ctrl-C after a checkpoint (128 + SIGINT, as shells report it); the same command or `resume` goes on.
EXIT_INTERRUPTED = 130
#: Seeds are whole numbers from 0 to this (what numpy's generators take in one 64-bit word).
MAX_SEED = 2**63 - 1


class Parser(argparse.ArgumentParser):
    """argparse with usage errors in one line (``structgen grow: error: argument --seed: ...``) and exit code 2,
    like every other error of the command line, instead of the usage block and then the error."""

    def error(self, message: str) -> Any:  # argparse's hook; it must not return
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def whole_number(low: int, high: int) -> Any:
    """An argparse ``type`` for whole numbers from ``low`` to ``high``; anything else is a usage error naming the
    option."""
    return limit_type(Limit(low, high, ""))


def finite_number(low: float = -math.inf, high: float = math.inf, *, above: bool = False) -> Any:
    """An argparse ``type`` for numbers from ``low`` (or above it, with ``above``) to ``high``; NaN, infinities and
    anything else are usage errors naming the option."""
    return limit_type(Limit(low, high, "", whole=False, above=above))


def limit_type(limit: Limit) -> Any:
    """An argparse ``type`` for the values ``limit`` admits: the one range check of the command line, whose message
    argparse prefixes with the option (``argument --updates: expected a whole number from 1 to 10,000,000, got
    0``)."""

    def parse(text: str) -> int | float:
        try:
            value: int | float = int(text) if limit.whole else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected {'a whole number' if limit.whole else 'a number'}, got {text!r}"
            ) from None
        if isinstance(value, float) and not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
        if not limit.admits(value):
            raise argparse.ArgumentTypeError(f"expected {limit.describe()}, got {f'{value:,}' if limit.whole else text}")
        return value

    return parse


def device_name(text: str) -> str:
    """An argparse ``type`` for torch device names (``cpu``, ``cuda``, ``cuda:N``, ``mps``); whether the machine has
    the device is checked when the work starts."""
    from structgen.devices import check_device_name

    try:
        return check_device_name(text, "device")
    except InputError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


class OutputFile(type(Path())):  # type: ignore[misc]
    """A path the command writes a file to (what :func:`output_path` returns): :func:`check_outputs` tells it from the
    command's inputs by this type."""


class OutputFolder(type(Path())):  # type: ignore[misc]
    """A folder the command writes (a run folder, an experiment's folder): see :class:`OutputFile`."""


def output_path(text: str) -> Path:
    """An argparse ``type`` for files a command will write: refused at once, before any work, if it cannot be
    written (its folder is a file, its name is too long, it is a folder)."""
    from evolution.files import InputFileError, check_output

    try:
        return OutputFile(check_output(text))
    except InputFileError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def output_folder(text: str) -> Path:
    """An argparse ``type`` for a folder a command writes (made, resumed, or with ``--overwrite`` replaced)."""
    return OutputFolder(text)


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse, before any work, a command whose output is one of its inputs: every value of ``args`` that names an
    existing file or folder and is not an output counts as an input (:func:`evolution.files.check_not_an_input`),
    and no two outputs may name the same file."""
    from evolution.files import check_not_an_input

    values = [value for name, value in vars(args).items() if name not in ("set", "handler")]
    flat = [item for value in values for item in (value if isinstance(value, (list, tuple)) else [value])]
    outputs = [item for item in flat if isinstance(item, (OutputFile, OutputFolder))]
    # By type, not by equality: an input given as a Path equals an output of the same name, and must stay an input.
    inputs = [item for item in flat if isinstance(item, (str, Path)) and not isinstance(item, (OutputFile, OutputFolder))]
    inputs = [item for item in inputs if _names_a_path(item)]
    replaced = bool(getattr(args, "overwrite", False))
    for number, target in enumerate(outputs):
        folder = isinstance(target, OutputFolder)
        check_not_an_input(target, inputs, folder=folder, replaced=folder and replaced)
        for other in outputs[:number]:
            if Path(other).absolute() == Path(target).absolute():
                raise InputError(f"{target}: named as two outputs of this command; give each its own file")


def _names_a_path(value: str | Path) -> bool:
    import os

    try:
        return os.path.lexists(value)
    except (ValueError, TypeError):  # a NUL byte: names nothing
        return False


def png_output_path(text: str) -> Path:
    """:func:`output_path` for a picture written as PNG: a name not ending in ``.png`` is refused before any work
    (PNG data under another suffix would mislead whatever opens it)."""
    path = output_path(text)
    if path.suffix.lower() != ".png":
        raise argparse.ArgumentTypeError(f"{text}: this option writes a PNG picture; give a name ending in .png")
    return path


def add_set_option(parser: argparse.ArgumentParser | Any, tables: str, example: str) -> None:
    """The ``--set KEY=VALUE`` option, the same in every subcommand (see :mod:`structgen.config` for the grammar)."""
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=f"change a setting of {tables} by its dotted name, or by the end of it when no other setting shares "
        f"that, e.g. {example} (repeatable; the named options are shortcuts for some of them)",
    )


def settings_from_args(roots: Mapping[str, Any], args: argparse.Namespace, shortcuts: Mapping[str, str] = {}) -> dict[str, Any]:
    """The settings objects in ``roots`` with the command's ``--set`` assignments applied, then its shortcut options.

    ``shortcuts`` maps an option's ``dest`` to the dotted setting it stands for (``{"iterations": "nca.iterations"}``);
    an option left at None was not given. Shortcut options apply last, so an option given by name wins over --set.
    """
    from structgen.config import apply_overrides

    given = [(key, getattr(args, dest)) for dest, key in shortcuts.items() if getattr(args, dest, None) is not None]
    return apply_overrides(roots, [*getattr(args, "set", []), *given])


#: One verb for each concept several domains share (make an item from a generator, judge it as the domain's score
#: does, draw it, summarise it, train an agent, run a paper's experiment, draw a paper's figure); a domain's own
#: verbs only where the concept is its own.
SHARED_VERBS = {
    "grow": "make one item from a generator",
    "evaluate": "judge one item as the domain's score does",
    "show": "draw one item",
    "info": "summarise a run folder or an item",
    "train": "train an agent",
    "experiment": "run a paper's experiment",
    "figure": "draw a paper's figure",
}
#: The release in which the verbs that :attr:`DomainCommands.renamed` lists stop answering.
RENAMED_VERBS_GO_IN = "0.5"


class VerbHelpFormatter(argparse.HelpFormatter):
    """argparse's formatter, but an epilog of examples keeps its lines as written, and a description keeps its
    paragraphs (each still wraps)."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        if text.startswith("examples:"):
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return "\n\n".join(super(VerbHelpFormatter, self)._fill_text(part, width, indent) for part in text.split("\n\n"))


def examples_epilog(examples: Iterable[str]) -> str:
    """A ``--help`` epilog listing ``examples`` (command lines), for :class:`VerbHelpFormatter`."""
    return "examples:\n" + "\n".join(f"  {line}" for line in examples)


class _VerbParsers:
    """``subparsers`` that give each verb its examples (:attr:`DomainCommands.examples`, as the ``--help`` epilog)
    and the old names :attr:`DomainCommands.renamed` lists as aliases; a verb typed by an old name says which
    replaces it (``structgen.cli`` prints it)."""

    def __init__(self, subparsers: Any, renamed: Mapping[str, str], examples: Mapping[str, Sequence[str]]) -> None:
        self._subparsers, self._renamed, self._examples = subparsers, renamed, examples

    def add_parser(self, name: str, **kwargs: Any) -> Any:
        if name in self._examples and "epilog" not in kwargs:
            kwargs.update(epilog=examples_epilog(self._examples[name]), formatter_class=VerbHelpFormatter)
        old = [before for before, after in self._renamed.items() if after == name]
        parser = self._subparsers.add_parser(name, aliases=[*kwargs.pop("aliases", []), *old], **kwargs)
        if old:
            parser.set_defaults(renamed_verbs={before: name for before in old})
        return parser

    def __getattr__(self, name: str) -> Any:
        return getattr(self._subparsers, name)


def renamed_verb_note(args: argparse.Namespace, typed: Iterable[str]) -> str | None:
    """What to say when one of the words ``typed`` on the command line is a verb's old name (None otherwise)."""
    renamed = getattr(args, "renamed_verbs", None) or {}
    for word in typed:
        if word in renamed:
            return f"'{word}' is now '{renamed[word]}'; the old name goes in structgen {RENAMED_VERBS_GO_IN}"
    return None


class DomainCommands:
    """What a domain adds to the command line. Subclass it, override what applies, and name an instance in the
    domain's spec (``commands="mypackage.cli:COMMANDS"``). Handlers raise :class:`InputError` for bad input."""

    #: The domain's verbs: name -> a function adding that verb's parser to ``subparsers``, usually a declared
    #: :class:`Verb` (``adders = verbs(verb("roll", cmd_roll, option(...)), ...)``). A concept in
    #: :data:`SHARED_VERBS` takes its verb there.
    adders: Mapping[str, Callable[[Any], None]] = {}
    #: Old verb names still answered for one release: old name -> its verb now.
    renamed: Mapping[str, str] = {}
    #: Examples (whole command lines) by verb, shown at the end of its ``--help``: for verbs the domain does not
    #: declare itself (``export``), or those declared without ``examples``.
    examples: Mapping[str, Sequence[str]] = {}

    def add_verbs(self, subparsers: Any, domain: DomainSpec, only: Collection[str] | None = None) -> None:
        """Add the domain's verbs to ``subparsers`` (all of them, or those named in ``only``, for the top-level
        shortcuts), each with its old names of :attr:`renamed`. Each verb's parser sets ``handler`` to a function of
        the parsed arguments returning the exit code. By default, the verbs of :attr:`adders`; an override builds on
        :meth:`verb_parsers`."""
        subparsers = self.verb_parsers(subparsers)
        for name in verbs_wanted(self.adders, only):
            self.adders[name](subparsers)

    def verb_parsers(self, subparsers: Any) -> Any:
        """``subparsers`` that give each verb its :attr:`examples` and :attr:`renamed`'s old names as aliases."""
        return _VerbParsers(subparsers, self.renamed, self.examples)

    def resume_run(self, kind: str, run_dir: Path, args: argparse.Namespace) -> int:
        """``structgen resume`` on a run folder of the domain that is not an evolution run: a search of its own, whose
        manifest names its ``run_kind``. ``args`` holds resume's options (``workers``, ``generations``,
        ``cluster``); returns the exit code."""
        raise InputError(f"{run_dir}: a {kind!r} run, which this domain cannot resume")

    def describe_run(self, kind: str, run_dir: Path) -> tuple[dict[str, Any], str]:
        """``structgen info`` on a run folder of the domain that is not an evolution run (its manifest names its
        ``run_kind``): a summary for ``--json`` and the text to print."""
        raise InputError(f"{run_dir}: a {kind!r} run, which this domain cannot describe")

    def describe_path(self, path: Path) -> tuple[dict[str, Any], str] | None:
        """``structgen info`` on a file of the domain (or a folder of its own that is no run folder): a summary for
        ``--json`` and the text to print; None when ``path`` is none of the domain's (the default)."""
        return None

    def report_view(self, problem: Any, genome: Any) -> dict[str, Any] | None:
        """How ``structgen report`` shows one elite (:mod:`structgen.runs.report`): ``{"figure": a Plotly figure as
        plain data (:func:`structgen.runs.report.plain_figure`), "verdict": a line, "fields": {name: number}}``, any
        of them left out. None (the default): the report shows the elite's objective, measures and fields only."""
        return None

    def report_file(self, path: Path) -> dict[str, Any] | None:
        """``structgen report FILE`` on a file of the domain: a view as :meth:`report_view` makes; None when ``path``
        is none of the domain's (the default)."""
        return None

    def add_export_options(self, parser: argparse.ArgumentParser) -> None:
        """Options for exporting this domain's files and elites; they appear in ``structgen export --help``, so
        give them names no other domain is likely to use."""

    def export_file(self, source: Path, output: Path, args: argparse.Namespace) -> str:
        """Write the domain's file ``source`` to ``output`` (in the format its suffix names); returns the line to
        print."""
        raise InputError(f"{source}: this domain has no files to export")

    def export_elite(self, problem: Any, genome: Any, output: Path, args: argparse.Namespace, origin: Mapping[str, str]) -> str:
        """Write what ``genome`` makes (a structure, a layout) to ``output``; ``origin`` names the run and elite it
        came from, for the file's metadata. Returns the line to print."""
        raise InputError(f"{output}: this domain has nothing to export")


def add_setting_options(
    parser: argparse.ArgumentParser,
    settings_class: type,
    fields: Iterable[str],
    label: str = "default",
    defaults: Mapping[str, Any] = {},
) -> None:
    """One option for each of ``fields`` of a settings dataclass, made from the field's
    :class:`structgen.config.Limit`: named ``--`` + the field with dashes (or the limit's ``option``), checked by the
    limit (:func:`limit_type`), helped by its text and the field's default as ``(label value)``. Each defaults to None
    (a field not given keeps the settings' value: :func:`given_settings`) unless ``defaults`` names the verb's own.
    The class is not built: building can check more than a parser needs (and load torch)."""
    shown = {item.name: item.default for item in dataclasses.fields(settings_class)} | dict(defaults)
    limits = limits_of(settings_class)
    for field in fields:
        limit = limits[field]
        parser.add_argument(
            limit.option or "--" + field.replace("_", "-"),
            dest=field,
            type=limit_type(limit),
            default=defaults.get(field),
            metavar="N" if limit.whole else "X",
            help=f"{limit.help} ({'default' if field in defaults else label} {shown[field]})",
        )


def given_settings(args: argparse.Namespace, fields: Iterable[str]) -> dict[str, Any]:
    """The fields that options added by :func:`add_setting_options` were given on the command line."""
    return {field: getattr(args, field) for field in fields if getattr(args, field) is not None}


def resumed_training_settings(run_dir: Path, args: argparse.Namespace, read_settings: Callable[[Any], Any], what: str) -> Any:
    """``structgen resume`` on an agent training's folder (one that trains in this process, by PPO updates): its
    settings, with ``--generations`` as the number of updates to reach."""
    import dataclasses

    from evolution import RunFolder

    if args.cluster is not None or args.workers is not None:
        raise InputError(f"{run_dir}: {what} runs in this process; give --generations (updates) only")
    settings = read_settings(RunFolder(run_dir))
    return settings if args.generations is None else dataclasses.replace(settings, updates=args.generations)


def seed_run_options(*, config_help: str, config_default: str | None, seeds: list[int], seeds_help: str) -> Adder:
    """The options every ``experiment`` verb shares (one run per seed, several at a time, then a table):
    ``OUT_DIR``, ``--config``, ``--seeds``, ``--parallel``, ``--optimizer`` and ``--json``. The experiment itself
    and how each run uses its processes are the verb's own."""
    from evolution.registry import OPTIMIZERS

    return _together(lambda parser: parser, [
        option("out_dir", type=output_folder, metavar="OUT_DIR", help="folder for the runs and the table (made if missing)"),
        option("--config", default=config_default, metavar="TOML", help=f"each run's configuration ({config_help})"),
        option("--seeds", type=whole_number(0, 2**31), nargs="+", default=seeds, metavar="S",
               help=f"run seeds, each once ({seeds_help})"),
        number("--parallel", 1, 1024, 2, "runs at once"),
        option("--optimizer", choices=list(OPTIMIZERS), default=None,
               help="run every seed with this optimiser instead of the configuration's; 'random' is random search at "
                    "the configuration's budget (as many evaluations a generation, the same archive cells): the "
                    "baseline the experiment's results are held against. Use another OUT_DIR for it"),
        json_flag("print the whole table as one JSON object, no progress bars"),
    ])  # fmt: skip


def write_by_suffix(output: Path, writers: Mapping[str, Callable[[Path], Any]], what: str) -> str:
    """Write ``output`` with the writer its suffix names (``{".json": save, ".png": draw}``); any other suffix is
    refused naming those that work. Returns the line an export prints."""
    writer = writers.get(output.suffix.lower())
    if writer is None:
        raise InputError(f"{output}: {what} exports as {' or '.join(writers)}")
    writer(output)
    return f"{output}: {what}"


def print_table(report: Mapping[str, Any], args: argparse.Namespace, markdown: Callable[[Any], str]) -> int:
    """An experiment's table on stdout: one JSON object with ``--json``, else its markdown."""
    import json

    print(json.dumps(report) if args.json else markdown(report), end="\n" if args.json else "")
    return EXIT_OK


def verbs_wanted(names: Iterable[str], only: Collection[str] | None) -> list[str]:
    """The verbs of ``names`` to add: all, or those in ``only``."""
    return [name for name in names if only is None or name in only]


# -- verbs declared: a verb is its handler plus its options, each option one call ---------------------------------------
#: An option (or a group of them) as a function that adds it to a parser or an argument group.
Adder = Callable[[Any], None]


def option(*names: str, help: str, **kwargs: Any) -> Adder:
    """One argument, declared: ``names`` and ``kwargs`` as argparse takes them. A default that says something (not
    None, False or an empty list) is appended to ``help`` as ``(default X)`` unless the help already names one."""
    default = kwargs.get("default")
    says_something = default is not None and default is not False and default != []
    if says_something and "default" not in help:
        help = f"{help} (default {default:g})" if isinstance(default, float) else f"{help} (default {default})"
    return lambda parser: parser.add_argument(*names, help=help, **kwargs)


def number(name: str, low: float, high: float, default: Any = None, help: str = "", **kwargs: Any) -> Adder:
    """A whole number from ``low`` to ``high`` (``metavar`` N unless given)."""
    return option(name, type=whole_number(int(low), int(high)), default=default, help=help, **{"metavar": "N", **kwargs})


def real(name: str, low: float, high: float, default: Any = None, help: str = "", *, above: bool = False, **kwargs: Any) -> Adder:
    """A finite number from ``low`` (or above it, with ``above``) to ``high`` (``metavar`` X unless given)."""
    kind = finite_number(low, high, above=above)
    return option(name, type=kind, default=default, help=help, **{"metavar": "X", **kwargs})


def flag(name: str, help: str) -> Adder:
    """An option that is given or not (``store_true``)."""
    return option(name, action="store_true", help=help)


def json_flag(help: str = "print one JSON object") -> Adder:
    """``--json``: the result as JSON on stdout instead of lines to read."""
    return flag("--json", help)


def output(metavar: str = "OUT", help: str = "file to write", *, required: bool = True, **kwargs: Any) -> Adder:
    """``-o/--output``: a file the verb writes, checked before any work (a ``.png`` metavar asks for a PNG name)."""
    kind = png_output_path if metavar.lower().endswith(".png") else output_path
    return option("-o", "--output", type=kind, metavar=metavar, required=required, help=help, **kwargs)


def seed(help: str, default: Any = 0, high: int = MAX_SEED, metavar: str = "N") -> Adder:
    """``--seed``: a whole number from 0 to ``high``."""
    return number("--seed", 0, high, default, help, metavar=metavar)


def device(default: str | None = None, help: str = "torch device: cpu, cuda, cuda:N") -> Adder:
    """``--device``: a torch device name (whether the machine has it is checked when the work starts)."""
    return option("--device", type=device_name, default=default, help=help if default else f"{help} (default: the CPU)")


def workers(help: str = "processes that share the work (default 0: this one); results do not depend on it", default=0) -> Adder:
    """``--workers``: local processes, 0 for none."""
    return number("--workers", 0, 1024, default, help)


def overwrite(what: str = "a run folder that holds another run") -> Adder:
    """``--overwrite``: replace ``what``, and never any other folder (the run folders' own check)."""
    return flag("--overwrite", f"replace {what} (never any other folder)")


def dpi() -> Adder:
    """``--dpi``: a picture's resolution."""
    return number("--dpi", 10, 1200, 110, "image resolution in dots per inch")


def nca_weights() -> Adder:
    """``--weights``: an NCA's weights, as ``evolution.files.read_weights`` reads them."""
    return option("--weights", metavar="FILE", help="NCA weights: .npy (1-D array) or .json (list of numbers)")


def one_of(*adders: Adder) -> Adder:
    """Options of which at most one may be given."""
    return _together(lambda parser: parser.add_mutually_exclusive_group(), adders)


def group(title: str, *adders: Adder) -> Adder:
    """Options shown together under ``title`` in ``--help``."""
    return _together(lambda parser: parser.add_argument_group(title), adders)


def _together(make_group: Callable[[Any], Any], adders: Sequence[Adder]) -> Adder:
    def add(parser: Any) -> None:
        grouped = make_group(parser)
        for add_one in adders:
            add_one(grouped)

    return add


def settings(settings_class: type, fields: Iterable[str], label: str = "default", defaults: Mapping[str, Any] = {}) -> Adder:
    """One option for each of ``fields`` of a settings dataclass (:func:`add_setting_options`)."""
    return lambda parser: add_setting_options(parser, settings_class, fields, label, defaults)


def set_option(tables: str, example: str) -> Adder:
    """``--set KEY=VALUE`` (:func:`add_set_option`)."""
    return lambda parser: add_set_option(parser, tables, example)


@dataclasses.dataclass(frozen=True)
class Verb:
    """A verb declared: its name, its handler and its options. Called with ``subparsers``, it adds its parser, which
    runs ``handler`` with ``defaults`` set. The help line is the first paragraph of the handler's docstring and the
    description the rest (each formatted with ``text`` and ``defaults``, so ``{kind}`` may stand for a value), unless
    given here: what a verb does is written once, beside the code that does it. ``examples`` (command lines) end its
    ``--help`` (:attr:`DomainCommands.examples` can also name a verb's, as it does for the generic ``export``)."""

    name: str
    handler: Callable[[argparse.Namespace], int]
    adders: Sequence[Adder]
    help: str | None = None
    description: str | None = None
    text: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    defaults: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    examples: Sequence[str] = ()

    def __call__(self, subparsers: Any) -> Any:
        first, _, rest = inspect.cleandoc(self.handler.__doc__ or "").partition("\n\n")
        values = {**self.defaults, **self.text}
        paragraphs = "\n\n".join(" ".join(part.split()) for part in rest.split("\n\n")).format(**values)
        parser = subparsers.add_parser(
            self.name,
            help=self.help if self.help is not None else " ".join(first.split()).format(**values),
            description=self.description if self.description is not None else paragraphs,
            formatter_class=VerbHelpFormatter,
            **({"epilog": examples_epilog(self.examples)} if self.examples else {}),
        )
        for add in self.adders:
            add(parser)
        parser.set_defaults(handler=self.handler, **self.defaults)
        return parser


def verb(
    name: str,
    handler: Callable[[argparse.Namespace], int],
    *adders: Adder,
    help: str | None = None,
    description: str | None = None,
    text: Mapping[str, Any] = {},
    examples: Sequence[str] = (),
    **defaults: Any,
) -> Verb:
    """Declare verb ``name`` (:class:`Verb`); ``defaults`` are set in the parsed arguments."""
    return Verb(name, handler, adders, help, description, dict(text), dict(defaults), tuple(examples))


def verbs(*declared: Verb, **defaults: Any) -> dict[str, Verb]:
    """Declared verbs by name, for :attr:`DomainCommands.adders`; ``defaults`` are set by every one of them."""
    return {item.name: dataclasses.replace(item, defaults={**defaults, **item.defaults}) for item in declared}
