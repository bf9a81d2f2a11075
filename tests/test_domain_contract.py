"""The contract every registered domain keeps, checked for each one (built in or installed as a plugin).

A new domain gets these tests by registering: determinism, batch independence, measures and fields as declared,
pickling, the genome's save/load round trip, and a run resumed after 1 generation ending like 2 straight ones. Each
domain runs under its spec's ``test_settings``, which keep evaluation to about a second.
"""

from __future__ import annotations

import json
import pickle
from typing import Any

import numpy as np
import pytest

from evolution import Evaluation, RunFolder
from evolution.runfolder import Best
from structgen import domains
from structgen.config import build
from structgen.experiment import load_experiment
from structgen.runs import evolve, resume
from tests.helpers import comparable

SPECS = domains.specs()
BATCH = 4


def flat_keys(table: dict[str, Any], prefix: str = "problem.") -> list[tuple[str, Any]]:
    pairs = []
    for key, value in table.items():
        if isinstance(value, dict):
            pairs += flat_keys(value, f"{prefix}{key}.")
        else:
            pairs.append((prefix + key, value))
    return pairs


def problem_of(spec: domains.DomainSpec) -> Any:
    return spec.make(build(spec.settings_type(), spec.test_settings, "problem"))


def batch(problem: Any, seed: int = 0) -> tuple[Any, np.ndarray]:
    genomes = problem.initial_genomes(BATCH, np.random.default_rng(seed))
    return genomes, np.random.SeedSequence(seed).generate_state(BATCH)


def assert_same(a: Evaluation, b: Evaluation) -> None:
    assert np.array_equal(a.objective, b.objective) and np.array_equal(a.measures, b.measures)
    assert a.fields.keys() == b.fields.keys()
    for name in a.fields:
        assert np.array_equal(a.fields[name], b.fields[name]), name


@pytest.fixture(scope="module", params=SPECS, ids=[spec.id for spec in SPECS])
def domain(request):
    spec = request.param
    problem = problem_of(spec)
    genomes, seeds = batch(problem)
    yield spec, problem, genomes, seeds, problem.evaluate(genomes, seeds)
    problem.close()


def test_the_spec_loads_and_its_main_job_is_valid(domain):
    spec, problem, *_ = domain
    assert isinstance(spec.default_settings(), spec.settings_type())
    assert domains.spec(spec.id) is spec and all(domains.spec(alias) is spec for alias in spec.aliases)
    experiment = load_experiment(domain=spec.id)
    experiment.make_optimizer(problem)  # the main job's optimiser works on this domain
    if spec.kernels:  # make install compiles them: a reference that does not load would fail every install
        assert callable(domains.load_reference(spec.kernels))


def test_evaluation_is_deterministic(domain):
    spec, problem, genomes, seeds, result = domain
    again_genomes, _ = batch(problem_of(spec))
    assert json.dumps([problem.genome_to_json(g) for g in genomes]) == json.dumps(
        [problem.genome_to_json(g) for g in again_genomes]
    )
    assert_same(problem_of(spec).evaluate(genomes, seeds), result)


def test_results_do_not_depend_on_how_a_batch_is_split(domain):
    spec, problem, genomes, seeds, result = domain
    parts = [problem.evaluate(genomes[a:b], seeds[a:b]) for a, b in ((0, 1), (1, 3), (3, BATCH))]
    assert_same(Evaluation.concatenate(parts), result)


def test_measures_and_fields_are_as_declared(domain):
    spec, problem, genomes, seeds, result = domain
    assert len(result) == BATCH
    assert len(problem.measure_names) == len(problem.measure_ranges)
    assert result.measures.shape == (BATCH, len(problem.measure_names))
    for k, (low, high) in enumerate(problem.measure_ranges):
        assert low < high
        assert ((result.measures[:, k] >= low) & (result.measures[:, k] <= high)).all(), problem.measure_names[k]
    assert set(result.fields) == set(problem.field_names)
    assert set(problem.plot_fields) <= set(problem.field_names)
    assert (result.objective >= problem.objective_floor).all()
    assert problem.flat == (problem.n_params is not None)
    if problem.flat:
        assert np.asarray(genomes).shape == (BATCH, problem.n_params)


def test_the_problem_pickles_and_evaluates_the_same_after(domain):
    spec, problem, genomes, seeds, result = domain
    assert_same(pickle.loads(pickle.dumps(problem)).evaluate(genomes, seeds), result)


def test_genomes_survive_a_save_and_load(domain, tmp_path):
    spec, problem, genomes, seeds, result = domain
    through_json = [problem.genome_from_json(json.loads(json.dumps(problem.genome_to_json(g)))) for g in genomes]
    if problem.flat:
        through_json = np.asarray(through_json)
    assert_same(problem.evaluate(through_json, seeds), result)
    folder = RunFolder.create(tmp_path / "run", "", {})
    best = Best(genomes[0], float(result.objective[0]), result.measures[0].tolist(), {}, 1)
    folder.write_best(best, problem)
    loaded = folder.best_genome(problem)
    first = problem.evaluate(np.asarray([loaded]) if problem.flat else [loaded], seeds[:1])
    assert_same(first, problem.evaluate(genomes[:1], seeds[:1]))


@pytest.mark.parametrize("spec", SPECS, ids=[spec.id for spec in SPECS])
def test_a_run_resumed_after_one_generation_ends_like_two_straight(spec, tmp_path):
    overrides = [*flat_keys(dict(spec.test_settings)), ("optimizer.population", 4), ("optimizer.parents", 2)]
    experiment = load_experiment(domain=spec.id, optimizer="ga", overrides=overrides, run_changes={"workers": 0, "seed": 5})
    straight, _ = evolve(experiment.with_run(generations=2), tmp_path / "straight", progress=False)
    split, _ = evolve(experiment.with_run(generations=1), tmp_path / "split", progress=False)
    resume(split.path, generations=2, progress=False)

    def outcome(folder: RunFolder) -> tuple[list, bytes, bytes]:
        metrics = comparable(folder.metrics())
        genome = next(p for p in (folder / "best").iterdir() if p.name.startswith("genome."))
        return metrics, genome.read_bytes(), (folder / "best" / "best.json").read_bytes()

    assert len(straight.metrics()) == 2
    assert outcome(split) == outcome(straight)
