"""The fortress through the generic run machinery: the original's MAP-Elites in miniature (its binning, 9 mutants and
1 random world a generation), a QD run killed with SIGKILL that resumes to the same archive, the robustness table,
and the domain's commands."""

from __future__ import annotations

import json

import numpy as np
import pytest
from ribs.archives import GridArchive

from evolution.optimizers import MapElitesSettings
from evolution.qd import map_elites
from evolution.runfolder import RunFolder
from structgen.domains.fortress.engine import simulate
from structgen.domains.fortress.formats import read_fortress_file
from structgen.domains.fortress.problem import FortressProblem, FortressSettings
from structgen.domains.fortress.world import random_world
from tests import reference
from tests.fortress.own_worlds import GARDEN, GEM_KEEPER, LONE_CLASS
from tests.helpers import cli, kill_during_evolve, outcome

DATA = reference.folder("amorphous-fortress")
needs_data = reference.needs("amorphous-fortress")

TINY = """\
[run]
generations = 6
seed = 3
workers = 0

[problem]
name = "fortress-v0"
steps = 15
sims = 2

[optimizer]
name = "map_elites"
cells = [100, 100]
batch_size = 5
immigrants = 1
variation = "problem"
"""


def test_cells_bin_measures_as_the_original_does():
    problem = FortressProblem()
    archive = GridArchive(solution_dim=1, dims=(100, 100), ranges=problem.measure_ranges)
    rng = np.random.default_rng(0)
    entities = np.concatenate([rng.uniform(0, 156, 300), [0, 156, 78, 1.56]])
    nodes = np.concatenate([rng.integers(15, 1411, 300), [15, 1410, 700, 29]]).astype(float)
    got = archive.int_to_grid_index(archive.index_of(np.stack([entities, nodes], axis=1)))
    original_x = [int(v / 156 * 99) for v in entities]
    original_y = [int((v - 15) / 1395 * 99) for v in nodes]
    assert got[:, 0].tolist() == original_x and got[:, 1].tolist() == original_y


def test_evaluation_is_the_mean_over_the_simulations():
    rng = np.random.default_rng(2)
    worlds = [random_world(rng) for _ in range(3)]
    problem = FortressProblem(FortressSettings(steps=30, sims=3, sim_seed=4))
    evaluation = problem.evaluate(worlds, np.zeros(3, dtype=np.int64))
    outcome_ = simulate(worlds, [4, 5, 6], 30)
    assert np.allclose(evaluation.objective, outcome_.fitness.mean(axis=1))
    assert np.allclose(evaluation.measures[:, 0], np.minimum(outcome_.entities, 156).mean(axis=1))
    assert evaluation.measures[:, 1].tolist() == [sum(len(e.nodes) for e in w.classes) for w in worlds]
    again = problem.evaluate(worlds, np.ones(3, dtype=np.int64))  # the engine's seeds do not matter
    assert np.array_equal(again.objective, evaluation.objective)


def test_a_generation_is_mutants_then_immigrants():
    class Counting(FortressProblem):
        made = immigrants = 0

        def initial_genomes(self, count, rng):
            self.made += count
            return super().initial_genomes(count, rng)

        def immigrant_genomes(self, count, rng):
            self.immigrants += count
            return super().immigrant_genomes(count, rng)

    problem = Counting(FortressSettings(steps=5, sims=1))
    optimizer = map_elites(problem, MapElitesSettings(cells=(100, 100), batch_size=10, immigrants=1, variation="problem"), 0)
    first = optimizer.ask()
    assert len(first) == 10 and (problem.made, problem.immigrants) == (10, 0)
    evaluation = problem.evaluate(first, np.zeros(10, dtype=np.int64))
    optimizer.tell(evaluation.objective, evaluation.measures, **evaluation.fields)
    second = optimizer.ask()
    assert len(second) == 10 and (problem.made, problem.immigrants) == (10, 1)


@pytest.mark.parametrize("measures", ["entities_nodes", "entities_entropy"])
def test_immigrants_are_drawn_by_total_nodes_whatever_the_measures(measures):
    # As the original: only the first population of an entropy run is drawn over entropy.
    problem = FortressProblem(FortressSettings(measures=measures, steps=5, sims=1))
    drawn = problem.immigrant_genomes(4, np.random.default_rng(3))
    rng = np.random.default_rng(3)
    assert [w.to_file() for w in drawn] == [random_world(rng, problem.variation, start="n_nodes").to_file() for _ in range(4)]


def test_genomes_round_trip_through_json():
    problem = FortressProblem()
    world = random_world(np.random.default_rng(9))
    again = problem.genome_from_json(json.loads(json.dumps(problem.genome_to_json(world))))
    assert again == world


def test_bad_settings_name_the_setting():
    with pytest.raises(ValueError, match="problem measures"):
        FortressSettings(measures="entities_edges")
    with pytest.raises(ValueError, match="problem next_to"):
        FortressSettings(next_to="hex")
    with pytest.raises(ValueError, match="problem steps"):
        FortressSettings(steps=0)
    with pytest.raises(ValueError, match="immigrants"):
        MapElitesSettings(batch_size=3, immigrants=4)


@pytest.mark.slow
def test_a_killed_fortress_run_resumes_to_the_same_archive(tmp_path, capsys):
    config = tmp_path / "fortress.toml"
    config.write_text(TINY)
    whole = tmp_path / "whole"
    code, out, err = cli(capsys, "evolve", config, "--run-dir", whole)
    assert code == 0, err
    rows = [json.loads(line) for line in (whole / "metrics.jsonl").read_text().splitlines()]
    assert [r["evaluations"] for r in rows] == [5, 10, 15, 20, 25, 30]
    assert rows[-1]["num_elites"] >= 5 and rows[-1]["qd_score"] > 0
    assert (whole / "best" / "world.txt").is_file() and (whole / "best" / "world.png").read_bytes()[:4] == b"\x89PNG"
    problem = FortressProblem(FortressSettings(steps=15, sims=2))
    genomes = RunFolder(whole).archive_genomes(problem)
    assert len(genomes) == rows[-1]["num_elites"] and not (whole / "archive_genomes.jsonl").exists()

    run = tmp_path / "killed"
    kill_during_evolve(config, run, 3, limit=300)
    written = {path.name: path.read_bytes() for path in (run / "genomes").glob("*.npz")}
    code, out, err = cli(capsys, "resume", run)
    assert code == 0, err
    assert outcome(run) == outcome(whole)
    assert RunFolder(run).archive_genomes(problem) == genomes
    # What the store had written before the kill is left as it was: checkpoints only add files.
    assert all((run / "genomes" / name).read_bytes() == data for name, data in written.items())

    # The robustness table: the archive as evolved, merged with itself, and re-evaluated.
    code, out, err = cli(capsys, "fortress", "robustness", whole, run, "--json", "-o", tmp_path / "table.json")
    assert code == 0, err
    table = json.loads(out)
    names = [row["name"] for row in table["rows"]]
    assert names[2] == "merged (2 runs)" and names[5].startswith("merged (2 runs), new seeds (15 ticks)")
    assert "5x longer (75 ticks)" in names[8] and len(names) == 9
    assert table["rows"][0]["qd_score"] == pytest.approx(rows[-1]["qd_score"])
    assert table["rows"][2]["cells"] == table["rows"][0]["cells"]  # the same archive twice
    assert table["rows"][3] == {**table["rows"][4], "name": table["rows"][3]["name"]}  # re-evaluation is deterministic
    assert json.loads((tmp_path / "table.json").read_text()) == table

    # Worlds of a run: by folder (best) or by cell.
    code, out, err = cli(capsys, "fortress", "evaluate", whole, "--steps", "15", "--json")
    assert code == 0, err
    index = (whole / "archive.csv").read_text().splitlines()[1].split(",")[0]
    code, out, err = cli(capsys, "export", whole, "--elite", f"index:{index}", "-o", tmp_path / "elite.txt")
    assert code == 0, err
    assert read_fortress_file(tmp_path / "elite.txt").classes


@pytest.mark.slow
def test_a_run_folder_of_the_text_format_still_reads(tmp_path, capsys):
    config = tmp_path / "fortress.toml"
    config.write_text(TINY)
    run = tmp_path / "run"
    assert cli(capsys, "evolve", config, "--run-dir", run)[0] == 0
    problem = FortressProblem(FortressSettings(steps=15, sims=2))
    genomes = RunFolder(run).archive_genomes(problem)
    # As earlier versions left it: one world per line as JSON text, no genome store.
    lines = "".join(json.dumps(problem.genome_to_json(world)) + "\n" for world in genomes)
    (run / "archive_genomes.jsonl").write_text(lines)
    (run / "archive_genome_keys.npy").unlink()
    assert RunFolder(run).archive_genomes(problem) == genomes
    index = (run / "archive.csv").read_text().splitlines()[1].split(",")[0]
    code, out, err = cli(capsys, "export", run, "--elite", f"index:{index}", "-o", tmp_path / "elite.txt")
    assert code == 0, err


def own_world(tmp_path, text: str, name: str = "world.txt"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_run_prints_the_final_map_and_the_population_of_each_class(tmp_path, capsys):
    path = own_world(tmp_path, GEM_KEEPER)
    code, out, err = cli(capsys, "fortress", "evaluate", path, "--steps", "30", "--seed", "2")
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0] == "#" * 15 and lines[7] == "#" * 15
    assert "stopped after" in lines[8] and lines[9].startswith("population: ")
    code, out, err = cli(capsys, "fortress", "evaluate", path, "--steps", "30", "--seed", "2", "--json")
    summary = json.loads(out)
    world = read_fortress_file(path)
    final = simulate([world], [2], 30, record=True).traces[0][0].entities[-1]
    assert sum(summary["populations"].values()) == len(final) == summary["entities"]


def test_running_an_entity_file_says_that_it_places_no_entities(tmp_path, capsys):
    # An entity file (the original's ENT/*.txt) defines one class and places nothing: an empty world, and the command
    # says why.
    code, out, err = cli(capsys, "fortress", "evaluate", own_world(tmp_path, LONE_CLASS, "lone.txt"), "--steps", "5")
    assert code == 0 and "0 entities" in out
    assert "places no entities (no -- INIT ENT POS -- or -- INIT FORT -- block)" in err
    code, out, err = cli(capsys, "fortress", "evaluate", own_world(tmp_path, GEM_KEEPER), "--steps", "5")
    assert code == 0 and "places no entities" not in err


@needs_data
def test_the_originals_files_run_from_the_command_line(capsys):
    for path in (DATA / "FORTS" / "LOCK_N_KEY.txt", DATA / "ENT" / "boko.txt"):
        code, out, err = cli(capsys, "fortress", "evaluate", path, "--steps", "5")
        assert code == 0 and out.splitlines()[0] == "#" * 15, err


def test_replay_and_show_write_their_pictures(tmp_path, capsys):
    path = own_world(tmp_path, GARDEN)
    gif, strip = tmp_path / "h.gif", tmp_path / "h.png"
    code, out, err = cli(capsys, "fortress", "replay", path, "--steps", "12", "--every", "4", "--gif", gif, "--strip", strip)
    assert code == 0, err
    assert out.count("-- tick") == 4  # 0, 4, 8, 12
    assert gif.read_bytes()[:6] == b"GIF89a" and strip.read_bytes()[:4] == b"\x89PNG"
    from PIL import Image

    assert 2 <= Image.open(gif).n_frames <= 13  # Pillow merges ticks where nothing moved into one longer frame
    code, out, err = cli(capsys, "fortress", "replay", path, "--steps", "12", "--seed", "3", "--json")
    assert code == 0, err
    replayed = json.loads(out)
    world = read_fortress_file(path)
    outcome_ = simulate([world], [3], 12, record=True)
    assert replayed["entities"] == [[list(e) for e in tick] for tick in outcome_.traces[0][0].entities]
    assert {c: set(v["edges"]) for c, v in replayed["visits"].items()} == {
        c: v["edges"] for c, v in outcome_.visit_sets(0, 0, [world]).items()
    }
    picture, populations = tmp_path / "w.png", tmp_path / "p.png"
    code, out, err = cli(capsys, "fortress", "show", path, "-o", picture, "--populations", populations)
    assert code == 0, err
    assert picture.read_bytes()[:4] == b"\x89PNG" and populations.read_bytes()[:4] == b"\x89PNG"


def test_bad_worlds_are_refused_with_their_place(tmp_path, capsys):
    code, out, err = cli(capsys, "fortress", "evaluate", tmp_path / "missing.txt")
    assert code != 0 and "missing.txt" in err
    bad = tmp_path / "bad.txt"
    bad.write_text("A\n-- NODES --\n0: add Q\n-- EDGES --\n\n-- INIT ENT POS --\nA-[2, 2]\n")
    code, out, err = cli(capsys, "fortress", "evaluate", bad)
    assert code != 0 and "bad.txt" in err and "add Q" in err
    code, out, err = cli(capsys, "fortress", "evaluate")
    assert code != 0 and "--random" in err
    code, out, err = cli(capsys, "fortress", "evaluate", "--random", "3", "--steps", "5")
    assert code == 0, err


def test_rebinning_keeps_the_best_of_a_cell_and_merging_the_best_of_the_runs():
    from structgen.domains.fortress.robustness import Elites, merge, rebin

    problem = FortressProblem()
    measures = np.array([[10.0, 100.0], [10.2, 100.0], [150.0, 1400.0], [10.1, 100.0]])
    elites = Elites(["a", "b", "c", "d"], np.array([0.2, 0.5, 0.1, 0.5]), measures, 5)
    fresh = rebin(problem, elites, (100, 100))
    assert fresh.worlds == ["b", "c"] and fresh.objective.tolist() == [0.5, 0.1]  # d ties b and came later
    other = Elites(["e"], np.array([0.3]), np.array([[150.0, 1400.0]]), 5)
    merged = merge(problem, [fresh, other], (100, 100))
    assert sorted(merged.worlds) == ["b", "e"] and merged.objective.sum() == pytest.approx(0.8)


def test_the_entropy_measures_start_from_worlds_spread_over_entropy():
    problem = FortressProblem(FortressSettings(measures="entities_entropy", steps=10, sims=1))
    assert problem.measure_names == ("entities", "entropy")
    worlds = problem.initial_genomes(12, np.random.default_rng(0))
    evaluation = problem.evaluate(worlds, np.zeros(12, dtype=np.int64))
    entropy = evaluation.measures[:, 1]
    assert ((0 <= entropy) & (entropy <= 1)).all() and len(set(np.round(entropy, 6))) > 3
    low, high = problem.measure_ranges[1]
    assert low == 0 and high == pytest.approx(100 / 99)


def test_work_beyond_the_memory_budget_is_refused_before_it_starts(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("STRUCTGEN_MEMORY_MB", "64")
    code, out, err = cli(capsys, "fortress", "evaluate", "--random", "1", "--steps", "1000000")
    assert code == 2 and "1,000,000 ticks of 1 worlds x 1 seeds, every tick recorded needs about" in err
    code, out, err = cli(capsys, "fortress", "evolve", "--set", "steps=2000000", "--run-dir", tmp_path / "run")
    assert code == 2 and "problem steps = 2,000,000 x sims = 5: one evaluation needs about" in err
    assert not (tmp_path / "run").exists()


def test_a_run_folder_of_another_domain_is_not_taken_for_a_world(tmp_path, capsys):
    code, out, err = cli(capsys, "evolve", "--domain", "ones-v0", "--generations", "1", "--run-dir", tmp_path / "ones")
    assert code == 0, err
    code, out, err = cli(capsys, "fortress", "evaluate", tmp_path / "ones")
    assert code == 2 and "a run of the ones-v0 domain, not a fortress run" in err
