"""Run configurations: the main job, TOML files and --set overrides, checked before any work."""

from __future__ import annotations

import pytest

from physics import PhysicsConfig
from structgen import domains
from structgen.config import ConfigError
from structgen.runs.experiment import load_experiment

STRUCTURES = domains.spec("structures-v0")


def test_the_main_job_is_the_papers_setup_with_its_special_rules_scaled_down():
    experiment = load_experiment()
    assert experiment.domain == "structures-v0" and experiment.optimizer_name == "ga"
    settings = experiment.problem_settings
    assert (settings.nca.hidden, settings.nca.iterations, settings.nca.cutoff, settings.nca.build_down) == (60, 5, 0.6, False)
    assert settings.nca.max_vertices == 64 and settings.physics == PhysicsConfig.preset("faithful")
    assert settings.evaluator == "statics"  # judged in milliseconds; the best's picture is simulated
    ga = experiment.optimizer_settings
    assert (ga.population, ga.parents) == (40, 8)  # the paper keeps the best fifth (20 of 100)
    assert experiment.run.generations == 200


def test_resolved_configuration_round_trips_through_toml(tmp_path):
    experiment = load_experiment(overrides=["problem.nca.cutoff=0.6", "problem.physics.height_mode='mean'", "run.seed=4"])
    path = tmp_path / "config.toml"
    path.write_text(experiment.to_toml())
    again = load_experiment(path)
    assert again == experiment
    assert again.problem_settings.physics.break_torque == float("inf")
    assert 'name = "structures-v0"' in path.read_text()


def test_a_preset_is_written_back_only_while_the_settings_equal_it(tmp_path):
    assert '[problem.physics]\npreset = "faithful"' in load_experiment().to_toml()
    changed = load_experiment(overrides=["physics.break_force=60"]).to_toml()
    assert "preset =" not in changed and "break_force = 60.0" in changed
    path = tmp_path / "c.toml"
    path.write_text(changed)
    assert load_experiment(path).problem_settings.physics == PhysicsConfig.preset("faithful", break_force=60.0)


@pytest.mark.parametrize("name", list(STRUCTURES.main_job.optimizers))
def test_switching_optimizer_in_the_main_job_keeps_a_comparable_size(name):
    experiment = load_experiment(optimizer=name)
    assert experiment.optimizer_name == name
    for key, value in STRUCTURES.main_job.optimizers[name].items():
        assert getattr(experiment.optimizer_settings, key) == (tuple(value) if isinstance(value, list) else value)


def test_random_search_in_place_of_the_optimiser_of_a_configuration_runs_at_its_budget(tmp_path):
    """``--optimizer random`` is the baseline of the configuration it is given: as many evaluations each
    generation (a GA's larger first generation too, since its parents are not evaluated again) and, for quality
    diversity, an archive of the same cells; what is set for random search itself is kept."""
    main = load_experiment(optimizer="random").optimizer_settings
    assert (main.initial, main.population, main.cells) == (40, 32, ())  # the main job's GA: 40, then 32 a generation
    path = tmp_path / "qd.toml"
    path.write_text('[problem]\nname = "sphere"\n[optimizer]\nname = "cma_mae"\nemitters = 3\nbatch_size = 7\ncells = [5, 6]\n')
    qd = load_experiment(path, optimizer="random")
    assert qd.optimizer_name == "random"
    assert (qd.optimizer_settings.population, qd.optimizer_settings.initial, qd.optimizer_settings.cells) == (21, 0, (5, 6))
    mine = load_experiment(path, optimizer="random", overrides=["optimizer.population=4"]).optimizer_settings
    assert (mine.population, mine.cells) == (4, (5, 6))
    assert load_experiment(path).optimizer_name == "cma_mae"  # the file alone still runs what it names
    path.write_text('[problem]\nname = "sphere"\n[optimizer]\nname = "cma_mae"\nemitters = 0\n')
    with pytest.raises(ConfigError, match="optimizer.emitters"):
        load_experiment(path, optimizer="random")


def test_every_domain_has_a_main_job_that_loads():
    for spec in domains.specs():
        experiment = load_experiment(domain=spec.id)
        assert experiment.domain == spec.id and experiment.optimizer_name == spec.main_job.optimizer


def test_a_file_sets_only_what_it_names(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('[run]\ngenerations = 3\n[problem]\nname = "sphere"\ndimensions = 4\n[optimizer]\nname = "cma_es"\n')
    experiment = load_experiment(path, overrides=["optimizer.sigma0=0.3"], run_changes={"seed": 9, "workers": None})
    assert experiment.domain == "sphere-v0"  # the name from before the registry still works
    assert experiment.run.generations == 3 and experiment.run.seed == 9
    assert experiment.problem_settings.dimensions == 4 and experiment.optimizer_settings.sigma0 == 0.3
    assert experiment.optimizer_settings.population == 100  # the optimiser's own default, not the main job's


def test_keys_may_be_shortened_to_any_tail_no_other_setting_shares():
    experiment = load_experiment(overrides=["cutoff=0.6", "nca.hidden=30", "physics.break_force=60", "generations=7"])
    assert experiment.problem_settings.nca.cutoff == 0.6 and experiment.problem_settings.nca.hidden == 30
    assert experiment.problem_settings.physics.break_force == 60 and experiment.run.generations == 7
    assert load_experiment(overrides=["evaluator=statics"]).problem_settings.evaluator == "statics"
    with pytest.raises(
        ConfigError, match=r"several settings have that name \(problem.nca.max_vertices, problem.physics.max_vertices\)"
    ):
        load_experiment(overrides=["max_vertices=10"])
    with pytest.raises(ConfigError, match=r"unknown setting 'cutof' \(did you mean cutoff\?\)"):
        load_experiment(overrides=["cutof=0.6"])


def test_a_preset_in_set_starts_the_table_from_it_whatever_the_order():
    experiment = load_experiment(overrides=["physics.break_force=70", "physics.preset=faithful"])
    assert experiment.problem_settings.physics == PhysicsConfig(break_force=70.0)


def test_a_configuration_of_one_domain_is_not_run_as_another(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('[problem]\nname = "ones"\n')
    assert load_experiment(path, domain="ones-v0").domain == "ones-v0"
    with pytest.raises(ConfigError, match="a configuration of the ones domain, not of structures-v0"):
        load_experiment(path, domain="structures-v0")


def test_combinations_that_cannot_work_fail_when_the_optimizer_is_built(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("[problem]\nname = 'ones'\n[optimizer]\nname = 'cma_es'\n")
    experiment = load_experiment(path)
    with pytest.raises(ConfigError, match="cma_es needs flat genomes"):
        experiment.make_optimizer(experiment.make_problem())
    experiment = load_experiment(overrides=["optimizer.name=map_elites", "optimizer.cells=[4, 4, 4]"])
    with pytest.raises(ConfigError, match="cells has 3 entries but structures has 2 measures"):
        experiment.make_optimizer(experiment.make_problem())


@pytest.mark.parametrize(
    "content, overrides, message",
    [
        ("[run]\ngenerations = 'ten'\n", [], r"run.generations = 'ten': expected an integer"),
        ("[run]\ngenerations = 3\nspeed = 1\n", [], r"unknown setting 'run.speed'"),
        ("[runs]\n", [], r"c.toml: unknown table \[runs\]"),
        (
            "[optimizer]\nname = 'de'\n",
            [],
            r"c.toml: unknown optimizer.name .de.; choose one of ga, cma_es, map_elites, cma_mae, random",
        ),
        (
            "[optimizer]\nname = 'ga'\nsigma0 = 0.1\n",
            [],
            r"unknown setting 'optimizer.sigma0'; optimizer has: population, parents",
        ),
        ("[optimizer]\npopulation = 10\nparents = 10\n", [], r"parents \(10\) must be fewer than population \(10\)"),
        ("[problem]\nname = 'maze'\n", [], r"c.toml: problem.name: unknown domain 'maze'; choose one of structures-v0, "),
        ("[problem.nca]\ncutoff = 1.5\n", [], r"NCA cutoff = 1.5: expected a number strictly between 0 and 1"),
        ("[problem.nca]\ncutof = 0.6\n", [], r"unknown setting 'problem.nca.cutof'"),
        (
            "[problem.physics]\npreset = 'turbo'\n",
            [],
            r"problem.physics.preset: unknown preset 'turbo'; choose one of faithful, fast",
        ),
        ("[problem.physics]\nbreak_force = 'strong'\n", [], r"problem.physics.break_force = 'strong': expected a number"),
        ("[problem]\nphysics = 3\n", [], r"problem.physics must be a table"),
        ("run = [", [], r"c.toml: not valid TOML"),
        ("", ["optimizer.population=abc"], r"optimizer.population = 'abc': expected an integer"),
        ("", ["run.generations"], r"expected key=value"),
        ("", ["run.generations=3", "run.generations.x=1"], r"run.generations is a value, not a table"),
    ],
)
def test_bad_configurations_fail_naming_the_key(tmp_path, content, overrides, message):
    path = tmp_path / "c.toml"
    path.write_text(content)
    with pytest.raises(ConfigError, match=message):
        load_experiment(path, overrides=overrides)
