"""Run configurations: the main job, TOML files and --set overrides, checked before any work."""

from __future__ import annotations

import pytest

from structgen.config import ConfigError
from structgen.experiment import MAIN_JOB_OPTIMIZERS, PROBLEMS, load_experiment


def test_the_main_job_is_the_papers_setup_scaled_down():
    experiment = load_experiment()
    assert experiment.problem_name == "structures" and experiment.optimizer_name == "ga"
    settings = experiment.problem_settings
    assert (settings.nca.hidden, settings.nca.iterations, settings.nca.cutoff, settings.nca.build_down) == (60, 5, 0.5, True)
    assert settings.physics.break_force == 52.5 and settings.physics_preset == "fast"
    ga = experiment.optimizer_settings
    assert ga.parents / ga.population == 0.2  # the paper keeps the best fifth (20 of 100)


def test_resolved_configuration_round_trips_through_toml(tmp_path):
    experiment = load_experiment(overrides=["problem.nca.cutoff=0.6", "problem.physics.height_mode='mean'", "run.seed=4"])
    path = tmp_path / "config.toml"
    path.write_text(experiment.to_toml())
    again = load_experiment(path)
    assert again == experiment
    assert again.problem_settings.physics.break_torque == float("inf")


@pytest.mark.parametrize("name", list(MAIN_JOB_OPTIMIZERS))
def test_switching_optimizer_in_the_main_job_keeps_a_comparable_size(name):
    experiment = load_experiment(optimizer=name)
    assert experiment.optimizer_name == name
    for key, value in MAIN_JOB_OPTIMIZERS[name].items():
        assert getattr(experiment.optimizer_settings, key) == (tuple(value) if isinstance(value, list) else value)


def test_a_file_sets_only_what_it_names(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('[run]\ngenerations = 3\n[problem]\nname = "sphere"\ndimensions = 4\n[optimizer]\nname = "cma_es"\n')
    experiment = load_experiment(path, overrides=["optimizer.sigma0=0.3"], run_changes={"seed": 9, "workers": None})
    assert experiment.run.generations == 3 and experiment.run.seed == 9
    assert experiment.problem_settings.dimensions == 4 and experiment.optimizer_settings.sigma0 == 0.3
    assert experiment.optimizer_settings.population == 100  # the optimiser's own default, not the main job's


@pytest.mark.parametrize(
    "content, overrides, message",
    [
        ("[run]\ngenerations = 'ten'\n", [], r"run.generations = 'ten': expected an integer"),
        ("[run]\ngenerations = 3\nspeed = 1\n", [], r"unknown setting 'run.speed'"),
        ("[runs]\n", [], r"c.toml: unknown table \[runs\]"),
        ("[optimizer]\nname = 'de'\n", [], r"c.toml: unknown optimizer.name 'de'; choose one of ga, cma_es, map_elites, cma_mae"),
        ("[optimizer]\nname = 'ga'\nsigma0 = 0.1\n", [], r"unknown setting 'optimizer.sigma0'; optimizer has: population, parents"),
        ("[optimizer]\npopulation = 10\nparents = 10\n", [], r"parents \(10\) must be fewer than population \(10\)"),
        ("[problem]\nname = 'maze'\n", [], r"unknown problem.name 'maze'; choose one of structures, sphere, ones"),
        ("[problem.nca]\ncutoff = 1.5\n", [], r"NCA cutoff must be a number strictly between 0 and 1"),
        ("[problem.nca]\ncutof = 0.6\n", [], r"unknown setting 'problem.nca.cutof'"),
        ("[problem.physics]\npreset = 'turbo'\n", [], r"problem.physics.preset: unknown physics preset 'turbo'"),
        ("[problem.physics]\nbreak_force = 'strong'\n", [], r"problem.physics.break_force = 'strong': expected a number"),
        ("[problem]\nphysics = 3\n", [], r"problem.physics must be a table"),
        ("[problem]\nname = 'ones'\n[optimizer]\nname = 'cma_es'\n", [], r"cma_es needs flat genomes"),
        ("[optimizer]\nname = 'map_elites'\ncells = [4, 4, 4]\n", [], r"cells has 3 entries but structures has 2 measures"),
        ("run = [", [], r"c.toml: not valid TOML"),
        ("", ["optimizer.population=abc"], r"optimizer.population = 'abc': expected an integer"),
        ("", ["generations=5"], r"--set generations: name the table too"),
        ("", ["run.generations"], r"expected key=value"),
    ],
)
def test_bad_configurations_fail_naming_the_key(tmp_path, content, overrides, message):
    path = tmp_path / "c.toml"
    path.write_text(content)
    with pytest.raises(ConfigError, match=message):
        load_experiment(path, overrides=overrides)


def test_every_registered_problem_builds_with_defaults():
    for name, entry in PROBLEMS.items():
        problem = entry.make(entry.read({}, "problem"))
        assert problem.name == name and len(problem.measure_names) == len(problem.measure_ranges) == 2
