"""The contract every domain keeps, as a function a domain's author calls (in the spirit of Gymnasium's env checker).

>>> from structgen import check_domain
>>> check_domain("sphere-v0").passed[:2]
('spec', 'determinism')

:func:`check_domain` evaluates a small batch under the spec's ``test_settings`` and checks, each by name:

- ``spec``: the settings dataclass builds with its defaults, the main job's optimiser works on the problem, and the
  kernels reference (if any) loads;
- ``determinism``: the same seed gives the same genomes, and a fresh problem gives the same results for them;
- ``batch independence``: evaluating the batch in parts gives what evaluating it whole gives;
- ``declared measures``: measures within their declared ranges, fields as declared, objectives above the floor, flat
  genomes of ``n_params``;
- ``pickling``: a pickled and unpickled problem evaluates the same (worker processes receive it that way);
- ``genome round trip``: genomes through JSON and through a run folder's ``best/`` evaluate the same;
- ``random search``: the baseline every domain's results are held against runs on it: ``--optimizer random``
  in place of the main job's optimiser asks a batch, takes its scores and, where the main job keeps an archive,
  fills one of the same cells;
- ``resume``: a run of 2 generations stopped after 1 and resumed ends exactly as one run straight (``ga``, 4
  candidates).

Every check runs even when an earlier one fails; :class:`DomainContractError` then lists each failure with its
reason. The suite's contract test (``tests/test_domain_contract.py``) calls this for every registered domain.
"""

from __future__ import annotations

import contextlib
import json
import pickle
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from structgen import registry

__all__ = ["CHECKS", "DomainCheck", "DomainContractError", "check_domain"]

#: The checks, in the order they run.
CHECKS = (
    "spec",
    "determinism",
    "batch independence",
    "declared measures",
    "pickling",
    "genome round trip",
    "random search",
    "resume",
)


class DomainContractError(AssertionError):
    """A domain broke its contract: ``failures`` holds ``(check, reason)`` for each check that failed."""

    def __init__(self, domain: str, failures: list[tuple[str, str]]) -> None:
        self.domain, self.failures = domain, failures
        lines = "\n".join(f"  {check}: {reason}" for check, reason in failures)
        super().__init__(f"domain {domain} breaks {len(failures)} of its contract's checks:\n{lines}")


@dataclass(frozen=True)
class DomainCheck:
    """What :func:`check_domain` found: the domain, the checks it passed (all that ran), and the seconds taken."""

    domain: str
    passed: tuple[str, ...]
    seconds: float


class _Broken(Exception):
    """One check's failure, with its reason."""


def _require(condition: bool, reason: str) -> None:
    if not condition:
        raise _Broken(reason)


def check_domain(
    spec: registry.DomainSpec | str,
    *,
    batch: int = 4,
    skip: Iterable[str] = (),
    folder: str | Path | None = None,
) -> DomainCheck:
    """Check a domain (a :class:`~structgen.registry.DomainSpec`, registered or not, or a registered id)
    against the contract (module doc). ``batch`` candidates are evaluated; ``skip`` names checks to leave out (of
    :data:`CHECKS`); the round trip and the resume write small run folders into a new folder inside ``folder``,
    kept there (default: a temporary folder, removed after).

    Raises:
        DomainContractError: one or more checks failed; every failure is listed.
        ValueError: ``skip`` names a check that does not exist, or ``batch`` is below 3.
    """
    began = time.perf_counter()
    spec = registry.spec(spec) if isinstance(spec, str) else spec
    skip = set(skip)
    if unknown := skip - set(CHECKS):
        raise ValueError(f"skip: no check named {', '.join(sorted(unknown))}; the checks are {', '.join(CHECKS)}")
    if not (isinstance(batch, int) and batch >= 3):
        raise ValueError(f"batch must be a whole number of at least 3 (it is split in three), got {batch!r}")
    passed: list[str] = []
    failures: list[tuple[str, str]] = []
    with _registered(spec), contextlib.ExitStack() as stack:
        problem = _problem(spec)
        stack.callback(getattr(problem, "close", lambda: None))
        genomes, seeds = _batch(problem, batch)
        result = problem.evaluate(genomes, seeds)
        if folder is None:
            where = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix=f"check-{spec.id}-")))
        else:  # a folder of its own inside, kept: runs never overwrite one another
            Path(folder).mkdir(parents=True, exist_ok=True)
            where = Path(tempfile.mkdtemp(prefix=f"check-{spec.id}-", dir=folder))
        checks: dict[str, Callable[[], None]] = {
            "spec": lambda: _check_spec(spec, problem),
            "determinism": lambda: _check_determinism(spec, problem, genomes, seeds, result, batch),
            "batch independence": lambda: _check_batches(problem, genomes, seeds, result, batch),
            "declared measures": lambda: _check_declared(problem, genomes, result, batch),
            "pickling": lambda: _same(pickle.loads(pickle.dumps(problem)).evaluate(genomes, seeds), result, "unpickled"),
            "genome round trip": lambda: _check_round_trip(problem, genomes, seeds, result, where / "round_trip"),
            "random search": lambda: _check_random_search(spec, problem, batch),
            "resume": lambda: _check_resume(spec, where),
        }
        for name in CHECKS:
            if name in skip:
                continue
            try:
                checks[name]()
            except _Broken as broken:
                failures.append((name, str(broken)))
            except Exception as error:  # a crash inside a check is the domain's failure too, reported with the rest
                failures.append((name, f"{type(error).__name__}: {error}"))
            else:
                passed.append(name)
    if failures:
        raise DomainContractError(spec.id, failures)
    return DomainCheck(spec.id, tuple(passed), time.perf_counter() - began)


@contextlib.contextmanager
def _registered(spec: registry.DomainSpec) -> Iterator[None]:
    """The resume check builds its run from the registry: a spec not registered yet is, for the check's duration."""
    known = spec.id in {s.id for s in registry.specs()}
    if known:
        yield
        return
    registry.register(spec)
    try:
        yield
    finally:
        registry.unregister(spec.id)


def _problem(spec: registry.DomainSpec) -> Any:
    from structgen.config import build

    return spec.make(build(spec.settings_type(), spec.test_settings, "problem"))


def _batch(problem: Any, size: int, seed: int = 0) -> tuple[Any, np.ndarray]:
    genomes = problem.initial_genomes(size, np.random.default_rng(seed))
    return genomes, np.random.SeedSequence(seed).generate_state(size)


def _same(a: Any, b: Any, what: str) -> None:
    """Two evaluations equal to the bit, or a reason naming ``what`` differed and where."""
    _require(np.array_equal(a.objective, b.objective), f"{what}: objectives differ ({a.objective} against {b.objective})")
    _require(np.array_equal(a.measures, b.measures), f"{what}: measures differ")
    _require(a.fields.keys() == b.fields.keys(), f"{what}: fields {sorted(a.fields)} against {sorted(b.fields)}")
    for name in a.fields:
        _require(np.array_equal(a.fields[name], b.fields[name]), f"{what}: field {name!r} differs")


def _check_spec(spec: registry.DomainSpec, problem: Any) -> None:
    from structgen.runs.experiment import load_experiment

    _require(isinstance(spec.default_settings(), spec.settings_type()), "the default settings are not its settings type")
    load_experiment(domain=spec.id).make_optimizer(problem)
    if spec.kernels:
        _require(callable(registry.load_reference(spec.kernels)), f"kernels {spec.kernels!r} is not a function")


def _check_random_search(spec: registry.DomainSpec, problem: Any, batch: int) -> None:
    from dataclasses import replace

    from evolution import make_optimizer
    from structgen.runs.experiment import load_experiment

    settings = load_experiment(domain=spec.id, optimizer="random").optimizer_settings
    search = make_optimizer("random", problem, replace(settings, population=batch, initial=0), seed=0)
    genomes = search.ask()
    _require(len(genomes) == batch, f"random search asked {len(genomes)} genomes for a population of {batch}")
    scores = problem.evaluate(genomes, np.random.SeedSequence(1).generate_state(batch))
    search.tell(scores.objective, scores.measures, **scores.fields)
    if settings.cells:
        _require(search.archive.stats.num_elites >= 1, f"random search's archive of cells {list(settings.cells)} is empty")


def _check_determinism(spec, problem, genomes, seeds, result, batch: int) -> None:
    again, _ = _batch(_problem(spec), batch)
    as_json = [json.dumps([problem.genome_to_json(g) for g in gs]) for gs in (genomes, again)]
    _require(as_json[0] == as_json[1], "the same seed drew other initial genomes")
    _same(_problem(spec).evaluate(genomes, seeds), result, "a second evaluation")


def _check_batches(problem, genomes, seeds, result, batch: int) -> None:
    from evolution import Evaluation

    cuts = (0, 1, batch // 2 + 1, batch)
    parts = [problem.evaluate(genomes[a:b], seeds[a:b]) for a, b in zip(cuts, cuts[1:])]
    _same(Evaluation.concatenate(parts), result, "the batch evaluated in parts")


def _check_declared(problem, genomes, result, batch: int) -> None:
    names, ranges = problem.measure_names, problem.measure_ranges
    _require(len(result) == batch, f"{len(result)} results for {batch} candidates")
    _require(len(names) == len(ranges), f"{len(names)} measure names but {len(ranges)} ranges")
    _require(result.measures.shape == (batch, len(names)), f"measures of shape {result.measures.shape}")
    for k, (low, high) in enumerate(ranges):
        _require(low < high, f"measure {names[k]!r}: range [{low}, {high}] is empty")
        values = result.measures[:, k]
        _require(((values >= low) & (values <= high)).all(), f"measure {names[k]!r}: {values} outside [{low}, {high}]")
    _require(set(result.fields) == set(problem.field_names), f"fields {sorted(result.fields)}, declared {problem.field_names}")
    _require(set(problem.plot_fields) <= set(problem.field_names), "plot_fields are not all fields")
    _require((result.objective >= problem.objective_floor).all(), f"objectives below the floor {problem.objective_floor}")
    _require(problem.flat == (problem.n_params is not None), "flat and n_params disagree")
    if problem.flat:
        shape = np.asarray(genomes).shape
        _require(shape == (batch, problem.n_params), f"flat genomes of shape {shape}, not ({batch}, {problem.n_params})")


def _check_round_trip(problem, genomes, seeds, result, folder: Path) -> None:
    from evolution import RunFolder
    from evolution.runfolder import Best

    through_json = [problem.genome_from_json(json.loads(json.dumps(problem.genome_to_json(g)))) for g in genomes]
    if problem.flat:
        through_json = np.asarray(through_json)
    _same(problem.evaluate(through_json, seeds), result, "genomes through JSON")
    run = RunFolder.create(folder, "", {})
    run.write_best(Best(genomes[0], float(result.objective[0]), result.measures[0].tolist(), {}, 1), problem)
    loaded = run.best_genome(problem)
    first = problem.evaluate(np.asarray([loaded]) if problem.flat else [loaded], seeds[:1])
    _same(first, problem.evaluate(genomes[:1], seeds[:1]), "the genome through a run folder's best/")


def _check_resume(spec: registry.DomainSpec, folder: Path) -> None:
    from evolution.run import comparable_metrics
    from structgen.config import flatten
    from structgen.runs import evolve, resume
    from structgen.runs.experiment import load_experiment

    overrides = [*flatten(spec.test_settings, "problem.").items(), ("optimizer.population", 4), ("optimizer.parents", 2)]
    experiment = load_experiment(domain=spec.id, optimizer="ga", overrides=overrides, run_changes={"workers": 0, "seed": 5})
    straight, _ = evolve(experiment.with_run(generations=2), folder / "straight", progress=False)
    split, _ = evolve(experiment.with_run(generations=1), folder / "split", progress=False)
    resume(split.path, generations=2, progress=False)

    def outcome(run) -> tuple[list, bytes, bytes]:
        metrics = comparable_metrics(run.metrics())
        genome = next(p for p in (run / "best").iterdir() if p.name.startswith("genome."))
        return metrics, genome.read_bytes(), (run / "best" / "best.json").read_bytes()

    _require(len(straight.metrics()) == 2, f"a run of 2 generations wrote {len(straight.metrics())} metrics rows")
    _require(outcome(split) == outcome(straight), "a run stopped after 1 generation and resumed ended elsewhere")
