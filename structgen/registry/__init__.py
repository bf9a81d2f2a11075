"""The domain registry: every domain structgen can evolve, by versioned id, in the spirit of Gymnasium's registry.

A domain binds a generator to a judge as an :class:`evolution.Problem`. It is described by a :class:`DomainSpec` made
of strings and plain data, so that listing domains, or building the command line, imports none of them: the problem
class, its settings dataclass and its command-line verbs are named as ``"module:attribute"`` and loaded on first use.

Where domains come from:

- built in: one line each in :data:`BUILTIN`, naming the spec inside the domain's package;
- from other packages: the entry-point group ``structgen.domains``. Each entry point names a :class:`DomainSpec`, or
  a function returning one (or several); a package that declares

  .. code-block:: toml

      [project.entry-points."structgen.domains"]
      dice = "dice_domain:DOMAIN"

  is evolved, resumed and exported by every generic command once it is installed. A plugin that fails to load is
  reported in a warning and left out; it never stops the others.
- at run time: :func:`register` (for tests and notebooks).
"""

from __future__ import annotations

import importlib
import logging
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any

__all__ = [
    "BUILTIN",
    "DEFAULT_DOMAIN",
    "ENTRY_POINT_GROUP",
    "DomainSpec",
    "MainJob",
    "OPTIMIZER_KERNELS",
    "UnknownDomainError",
    "compile_kernels",
    "load_reference",
    "make",
    "register",
    "spec",
    "specs",
    "unregister",
]

log = logging.getLogger(__name__)

#: The built-in domains, one line each: where each domain's package keeps its spec.
BUILTIN = (
    "structgen.domains.structures:DOMAIN",
    "structgen.domains.toys:SPHERE",
    "structgen.domains.toys:ONES",
    "structgen.domains.layouts:WAREHOUSE",
    "structgen.domains.layouts:MANUFACTURING",
    "structgen.domains.layouts:MAZE",
    "structgen.domains.autoverse:AUTOVERSE",
    "structgen.domains.fortress:FORTRESS",
)
#: The domain of ``structgen evolve`` with no configuration, and of configurations that name none.
DEFAULT_DOMAIN = "structures-v0"
#: The entry-point group other packages register their domains in.
ENTRY_POINT_GROUP = "structgen.domains"

_ID = re.compile(r"^[a-z][a-z0-9_]*(-[a-z0-9_]+)*-v[0-9]+$")


class UnknownDomainError(KeyError):
    """No domain is registered under that name."""

    def __str__(self) -> str:
        return str(self.args[0])


def load_reference(reference: str) -> Any:
    """The object a ``"package.module:attribute"`` string names."""
    module, sep, attribute = reference.partition(":")
    if not sep or not module or not attribute:
        raise ValueError(f"{reference!r} is not of the form 'package.module:attribute'")
    target: Any = importlib.import_module(module)
    for part in attribute.split("."):
        target = getattr(target, part)
    return target


@dataclass(frozen=True)
class MainJob:
    """What ``structgen evolve`` runs for a domain when no configuration file is given: a few minutes' run that shows
    the domain at work.

    Attributes:
        run: ``[run]`` settings (``workers`` defaults to one per CPU, at most 8).
        problem: ``[problem]`` settings beyond the domain's defaults.
        optimizer: the optimiser's name.
        optimizers: for each optimiser, its ``[optimizer]`` settings in this job, so that ``--optimizer`` switches to
            a run of comparable size.
    """

    run: Mapping[str, Any] = field(default_factory=dict)
    problem: Mapping[str, Any] = field(default_factory=dict)
    optimizer: str = "ga"
    optimizers: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)


@dataclass(frozen=True)
class DomainSpec:
    """A domain, described without importing it.

    Attributes:
        id: versioned name, ``name-vN`` (``structures-v0``); a change that alters results gets a new version.
        entry_point: ``"module:attribute"`` of the problem factory, called with a settings object.
        settings: ``"module:attribute"`` of the settings dataclass (the ``[problem]`` table; every field defaulted).
        summary: one line for ``structgen list domains``.
        main_job: what ``structgen evolve`` runs for this domain without a configuration file.
        commands: ``"module:attribute"`` of a :class:`structgen.registry.commands.DomainCommands` that adds the domain's own
            verbs (``structgen <group> <verb>``) and exports its files and elites; None if it adds nothing.
        group: the name of the domain's command group; defaults to the id without its version.
        shortcuts: verbs of the domain also offered at the top level (``structgen grow`` for ``structgen structures
            grow``).
        aliases: other names ``problem.name`` may use for this domain (names from before the registry).
        libraries: distributions whose versions a run's manifest records, beyond the engine's own.
        test_settings: ``[problem]`` settings under which evaluating a handful of candidates takes a second or so:
            the contract tests run every domain with them.
        kernels: ``"module:function"`` that compiles the domain's numba functions (or loads them from numba's cache)
            by running a small case; :func:`compile_kernels` calls it at install time, so that a first use does not
            spend a minute compiling. None for a domain without compiled code.
    """

    id: str
    entry_point: str
    settings: str
    summary: str
    main_job: MainJob = field(default_factory=MainJob)
    commands: str | None = None
    group: str | None = None
    shortcuts: tuple[str, ...] = ()
    aliases: tuple[str, ...] = ()
    libraries: tuple[str, ...] = ()
    test_settings: Mapping[str, Any] = field(default_factory=dict)
    kernels: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not _ID.match(self.id):
            raise ValueError(f"domain id {self.id!r} must look like 'name-v0' (lower case, a version at the end)")
        for name in ("entry_point", "settings", "commands", "kernels"):
            value = getattr(self, name)
            if value is not None and (not isinstance(value, str) or ":" not in value):
                raise ValueError(f"domain {self.id}: {name} must be a 'module:attribute' string, got {value!r}")
        if not isinstance(self.summary, str) or not self.summary or "\n" in self.summary:
            raise ValueError(f"domain {self.id}: summary must be one line of text")

    @property
    def group_name(self) -> str:
        """The command group: ``structgen <group> <verb>``."""
        return self.group or self.id.rsplit("-v", 1)[0]

    def settings_type(self) -> type:
        """The settings dataclass (imports the domain)."""
        return load_reference(self.settings)

    def default_settings(self) -> Any:
        return self.settings_type()()

    def make(self, settings: Any = None) -> Any:
        """The domain's problem, with ``settings`` or the defaults."""
        return load_reference(self.entry_point)(self.default_settings() if settings is None else settings)

    def command_hooks(self) -> Any:
        """The domain's :class:`structgen.registry.commands.DomainCommands`, or None."""
        return load_reference(self.commands) if self.commands else None


_registry: dict[str, DomainSpec] = {}
_aliases: dict[str, str] = {}
_loaded = False


def register(domain: DomainSpec) -> DomainSpec:
    """Add a domain; an id or alias already taken is an error."""
    _load()
    return _add(domain)


def unregister(name: str) -> DomainSpec:
    """Remove the domain registered as ``name`` (an id or an alias) and return it: for a plugin's tests, and for
    :func:`structgen.check_domain`, which registers a spec for the length of its check."""
    found = spec(name)
    del _registry[found.id]
    for alias in found.aliases:
        _aliases.pop(alias, None)
    return found


def _add(domain: DomainSpec) -> DomainSpec:
    if not isinstance(domain, DomainSpec):
        raise TypeError(f"expected a DomainSpec, got {type(domain).__name__}")
    for name in (domain.id, *domain.aliases):
        if name in _registry or name in _aliases:
            raise ValueError(f"domain name {name!r} is already registered")
    _registry[domain.id] = domain
    _aliases.update({alias: domain.id for alias in domain.aliases})
    return domain


def _load() -> None:
    """Register the built-in domains, then those of installed packages (once)."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    for reference in BUILTIN:
        _add(load_reference(reference))
    for entry in metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            found = entry.load()
            if callable(found) and not isinstance(found, DomainSpec):
                found = found()
            for domain in [found] if isinstance(found, DomainSpec) else list(found or ()):
                _add(domain)
        except Exception as err:  # a broken plugin must not take structgen down with it
            log.warning("domain plugin %s = %s not loaded: %s: %s", entry.name, entry.value, type(err).__name__, err)


def specs() -> list[DomainSpec]:
    """Every registered domain: built-in ones first, in registration order."""
    _load()
    return list(_registry.values())


def spec(name: str) -> DomainSpec:
    """The domain registered as ``name`` (an id or an alias)."""
    _load()
    found = _registry.get(_aliases.get(name, name))
    if found is None:
        raise UnknownDomainError(f"unknown domain {name!r}; choose one of {', '.join(_registry)}")
    return found


#: The optimisers' compiled code (pyribs's evolution strategies), compiled at install with the domains'.
OPTIMIZER_KERNELS = "evolution.qd:compile_kernels"


def compile_kernels() -> list[str]:
    """Compile the optimisers' and every domain's numba functions into numba's on-disk cache (``make install`` does
    this once); returns the kernels' references, each once however many domains share it."""
    log.info("compiling the optimisers' kernels (%s)", OPTIMIZER_KERNELS)
    load_reference(OPTIMIZER_KERNELS)()
    done: list[str] = [OPTIMIZER_KERNELS]
    for domain in specs():
        if domain.kernels and domain.kernels not in done:
            log.info("compiling %s's kernels (%s)", domain.id, domain.kernels)
            load_reference(domain.kernels)()
            done.append(domain.kernels)
    return done


def make(name: str, settings: Any = None) -> Any:
    """The problem of the domain ``name``, with ``settings`` or the defaults (like ``gymnasium.make``)."""
    return spec(name).make(settings)
