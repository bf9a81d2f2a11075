"""The paper's experiment as a problem: evolve local NCAs whose structures stand, grow tall and grow complex.

## Genome
The flat weight vector of a local NCA (4766 numbers for the paper's 52-60-26 network). Random genomes are uniform in
``[-init_scale, init_scale]``.

## Phenotype
The structure the NCA grows from one seed vertex (:mod:`structgen.nca`, settings in ``[problem.nca]``).

## Objective
The paper's score Q = I + (Wh * H + Wc * C) * I from a PyBullet stability check (:mod:`physics`, settings in
``[problem.physics]``, fast preset by default), or from the static frame solve, or from the first moments of the
simulation with joints that hold (``problem.evaluator``). Structures the check refuses (over its size caps) score 0,
as do those lower than ``problem.min_height``.

## Measures
``height`` (H, lattice units) and ``vertices`` (C), for quality-diversity archives. Their ranges are centred on
whole numbers, so a structure that sags from height 3 to 2.998 stays in the cell of height 3.

## Fields
``integrity`` (the transient evaluator's strength ratio), ``height``, ``complexity``, ``standing_height`` (the
height if no joint broke, or none would have, and nothing was still falling when the simulation ended, else 0),
``edges``, ``broken_joints``, ``settled`` (0/1), ``failed`` (0/1: the check refused the structure), ``capped`` (0/1:
growth stopped at the NCA's vertex cap), ``evaluator`` (0: scored by the static solve, 1: by the simulation, 2: by
the collapse screen), and with the transient evaluator ``peak_force`` (N), with the screened one
``standing_vertices`` and ``standing_edges`` (the size of a structure that stands, else 0). Metrics record each
generation's maximum of every field, so the tallest standing structure of a run is there even when it was not the
best-scoring one, and the mean of ``integrity``, ``complexity`` and ``edges``.

## The paper's special rules
As settings: ``problem.nca.cutoff`` (activation cutoff, 0.6 in the paper's variant), ``problem.nca.build_down =
false`` (no building below the seed), ``problem.physics.height_mode = "mean"`` (average height instead of height).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from evolution import Evaluation, Problem
from evolution.files import atomic_write
from physics import PhysicsConfig, StabilityReport, check_stability, check_transient
from physics.model import InputError
from physics.statics import check_collapse, check_statics_with_loads, overload_ratio
from structgen.config import Limit, check_limits
from structgen.nca import INIT_SCALE, LocalNCA, NCAConfig, _split, grow, grow_population, n_params
from structgen.nca_config import MAX_ITERATIONS
from structgen.structure import Structure

__all__ = ["EVALUATORS", "StableStructures", "StructuresSettings"]

EVALUATORS = ("bullet", "statics", "statics+bullet", "screened", "transient")
_BY_STATICS, _BY_BULLET, _BY_SCREEN = 0.0, 1.0, 2.0
_EVALUATOR_CODE = {"statics": _BY_STATICS, "collapse": _BY_SCREEN}


@dataclass(frozen=True)
class StructuresSettings:
    """The ``[problem]`` table of the structures domain.

    Attributes:
        init_scale: random genomes are uniform in [-init_scale, init_scale] (the paper's range by default).
        evaluator: how structures are judged: "bullet" (simulation), "statics" (the static frame solve of
            :mod:`physics.statics`, milliseconds), or "statics+bullet" (statics for every structure, then the
            simulation for each one statics predicts to stand or to come close: the candidates for best), or
            "transient" (:func:`physics.check_transient`: the first ``transient_window`` seconds with joints that
            hold, Q with I replaced by the strength ratio min(1, break force / largest joint force), which keeps
            falling as the peak rises where integrity moves a joint at a time, so a search can refine a structure
            that almost stands: ``optimizer.x0``, ``configs/tall_six_refine.toml``), or "screened" (the paper's
            experiments at full size: a structure whose :func:`physics.statics.overload_ratio` is above
            ``collapse_ratio`` is scored as falling apart entirely, without a solve; the rest as "statics+bullet").
            The field ``evaluator`` records which one scored each candidate (0 statics, 1 simulation or transient,
            2 the collapse screen).
        screen_margin: "statics+bullet" also simulates a structure statics predicts to break when no joint of the
            intact structure is loaded beyond ``screen_margin`` times the break force. Statics is approximate where
            the load can take several paths (a star on five legs): the rare early structures that stand are then
            often predicted to break by a few percent, and a screen without a margin starved runs of every standing
            structure (benchmarks/structures.md, "Statics as a screen"). 1 screens on the prediction alone; ``inf``
            simulates every structure the static analysis can answer for (with "screened", all that the collapse
            screen lets through). The static integrity of a structure that partly breaks is no guide to the
            simulation's: on the no-build-down runs' populations (200 to 490 vertices, most joints holding) it ranks
            them as the faithful preset does with Spearman's rho 0.4 where the fast preset reaches 0.9, at 7 s of
            CPU a structure instead of 0.5 (benchmarks/structures.md, "The paper's experiments").
        collapse_ratio: the "screened" evaluator's threshold. Random networks with five growth steps build blocks of
            about a thousand vertices (5,000 to 7,000 edges) whose joints at the worst level are loaded 3 to 130 times
            over; the simulation crushes them and keeps almost none of their joints, and a static solve of each
            takes seconds. ``benchmarks/structures_paper_judge.py`` measures the screen against the faithful preset.
        transient_window: simulated seconds the transient evaluator runs (the spawn transient, where tall
            structures carry their largest loads, is over within the first 0.3 s).
        min_height: structures lower than this (H, lattice units, as judged) score 0. For refining at a height: the
            paper's Q lets a structure one level taller outrank a standing one only while its integrity (or strength
            ratio) stays above about H/(H + 1), so a refinement of a near miss one level up drifts between the two;
            the floor keeps it at the height it is after. 0 (default): no floor.
        also_grow: more growth lengths (steps) each NCA is grown for and judged at besides ``nca.iterations``, to
            train weights whose structures keep standing as they grow on ("train small, grow large"). The objective
            becomes Q at ``nca.iterations`` times the lowest integrity among these lengths; the field
            ``grown_integrity`` records that lowest integrity. Longer growths are larger: judge them with
            ``evaluator = "statics"`` and raise ``nca.max_vertices`` (growth stops before passing it).
        nca: the NCA's shape and growth rules (``[problem.nca]``). The default vertex cap of 64 keeps random
            networks, which fill their growth box with about 1,100 vertices, within what a simulation can judge
            in a search loop: growth stops before the step that would exceed it.
        physics: the physics settings (``[problem.physics]``), the fast preset unless the table names another
            (``preset = "faithful"``).
    """

    section: ClassVar[str] = "problem"
    limits: ClassVar[dict[str, Limit]] = {
        "init_scale": Limit(0, 1e6, "random genomes' range", whole=False, above=True, below=True),
        "collapse_ratio": Limit(1, 1e6, "the screened evaluator's threshold", whole=False),
        "transient_window": Limit(0, 3600, "simulated seconds of the transient evaluator", whole=False, above=True),
        "min_height": Limit(0, 1e6, "structures lower than this (lattice units) score 0", whole=False),
    }

    init_scale: float = INIT_SCALE
    evaluator: str = "bullet"
    screen_margin: float = 1.5
    collapse_ratio: float = 2.5
    transient_window: float = 0.3
    min_height: float = 0.0
    also_grow: tuple[int, ...] = ()
    nca: NCAConfig = field(default_factory=lambda: NCAConfig(max_vertices=64))
    physics: PhysicsConfig = field(default_factory=lambda: PhysicsConfig.preset("fast"))

    def __post_init__(self) -> None:
        check_limits(self)
        if self.evaluator not in EVALUATORS:
            raise ValueError(f"problem evaluator must be one of {', '.join(EVALUATORS)}, got {self.evaluator!r}")
        lengths = self.also_grow
        if isinstance(lengths, list):  # as a TOML array arrives
            object.__setattr__(self, "also_grow", lengths := tuple(lengths))
        if not isinstance(lengths, tuple) or not all(
            isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= MAX_ITERATIONS for n in lengths
        ):
            raise ValueError(f"problem also_grow must be a list of growth lengths from 1 to {MAX_ITERATIONS}, got {lengths!r}")
        margin = self.screen_margin
        if not (isinstance(margin, (int, float)) and not isinstance(margin, bool) and margin >= 1):
            raise ValueError(f"problem screen_margin must be a number of at least 1 (or inf), got {margin!r}")


class StableStructures(Problem):
    """Genomes are NCA weights; the objective is the paper's Q from a physics check of the grown structure."""

    name = "structures"
    measure_names = ("height", "vertices")
    field_names = (
        "integrity",
        "height",
        "complexity",
        "standing_height",
        "edges",
        "broken_joints",
        "settled",
        "failed",
        "capped",
        "evaluator",
    )
    plot_fields = ("integrity", "height", "complexity")
    # The paper's Table 1 sorts generations by their mean integrity; sizes tell why they cost what they cost.
    mean_fields = ("integrity", "complexity", "edges")

    def __init__(self, settings: StructuresSettings | None = None) -> None:
        self.settings = settings or StructuresSettings()
        if self.settings.evaluator == "transient":
            self.field_names = (*self.field_names, "peak_force")
        if self.settings.evaluator == "screened":  # the paper's experiments' table needs them; older runs lack them
            self.field_names = (*self.field_names, "standing_vertices", "standing_edges")
        if self.settings.also_grow:
            self.field_names = (*self.field_names, "grown_integrity")
        nca = self.settings.nca
        self.n_params = n_params(nca)
        reach = min(nca.iterations, nca.max_extent)
        tallest = 2 * reach if nca.build_down else reach
        self.measure_ranges = ((-0.5, tallest + 0.5), (0.5, nca.max_vertices + 0.5))

    def initial_genomes(self, count: int, rng: np.random.Generator) -> np.ndarray:
        scale = self.settings.init_scale
        return rng.uniform(-scale, scale, size=(count, self.n_params))

    def evaluate(self, genomes: np.ndarray, seeds: np.ndarray) -> Evaluation:
        structures = grow_population(np.asarray(genomes, dtype=np.float64), self.settings.nca)
        reports = [self.judge(s) for s in structures]
        fields = {
            "integrity": [r.integrity for r in reports],
            "height": [r.height for r in reports],
            "complexity": [r.complexity for r in reports],
            "standing_height": [r.height if r.stands else 0.0 for r in reports],
            "edges": [s.n_edges for s in structures],
            "broken_joints": [len(r.broken_joints) for r in reports],
            "settled": [float(r.settled) for r in reports],
            "failed": [float(r.error is not None) for r in reports],
            "capped": [float(s.metadata["growth"]["hit_max_vertices"]) for s in structures],
            "evaluator": [_EVALUATOR_CODE.get(r.method, _BY_BULLET) for r in reports],
        }
        measures = np.array([[r.height, r.complexity] for r in reports], dtype=np.float64).reshape(-1, 2)
        objective = np.array([r.score if r.height >= self.settings.min_height else 0.0 for r in reports])
        if self.settings.evaluator == "transient":
            fields["peak_force"] = [r.peak_force for r in reports]
        if self.settings.evaluator == "screened":
            fields["standing_vertices"] = [float(s.n_vertices) if r.stands else 0.0 for s, r in zip(structures, reports)]
            fields["standing_edges"] = [float(s.n_edges) if r.stands else 0.0 for s, r in zip(structures, reports)]
        if self.settings.also_grow:
            lowest = self.grown_integrity(genomes).min(axis=1)
            fields["grown_integrity"] = lowest.tolist()
            objective = objective * lowest
        return Evaluation(objective, measures, fields)

    def grown_integrity(self, genomes: np.ndarray, lengths: Sequence[int] | None = None) -> np.ndarray:
        """``(genomes, lengths)`` integrity of each genome's structure grown for each length (default
        ``also_grow``), judged by the configured evaluator."""
        lengths = self.settings.also_grow if lengths is None else lengths
        genomes = np.asarray(genomes, dtype=np.float64).reshape(-1, self.n_params)
        columns = []
        for steps in lengths:
            longer = grow_population(genomes, replace(self.settings.nca, iterations=steps))
            columns.append([self.judge(s).integrity for s in longer])
        return np.array(columns, dtype=np.float64).T.reshape(len(genomes), len(lengths))

    def judge(self, structure: Structure) -> StabilityReport:
        """The report that scores one structure, by the configured evaluator; never raises for bad structures.

        The choice for "statics+bullet" depends on the structure alone, so results do not depend on how a
        batch is split between workers.
        """
        physics = self.settings.physics
        if self.settings.evaluator == "bullet":
            return check_stability(structure, physics, errors="report")
        if self.settings.evaluator == "transient":
            return check_transient(structure, physics, window=self.settings.transient_window, errors="report")
        if self.settings.evaluator == "screened":
            try:
                if overload_ratio(structure, physics) > self.settings.collapse_ratio:
                    return check_collapse(structure, physics)
            except InputError:
                pass  # the static analysis below reports the same problem as a failed check
        predicted, loads = check_statics_with_loads(structure, physics)
        if self.settings.evaluator == "statics" or not self._worth_simulating(predicted, loads):
            return predicted
        return check_stability(structure, physics, errors="report")

    def _worth_simulating(self, predicted: StabilityReport, loads: np.ndarray) -> bool:
        """The "statics+bullet" screen: predicted to stand, or supported and with the intact structure's joint loads
        within the screen margin."""
        if predicted.intact:
            return True
        if not len(loads) or np.isnan(loads).any():  # nothing to judge, or a piece with no static answer: it falls
            return False
        return bool(loads.max() <= self.settings.screen_margin * self.settings.physics.break_force)

    def crossover(self, first: np.ndarray, second: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The paper's most promising recombination: the child is ``first`` with one hidden neuron (its incoming
        weights, bias and outgoing weights) taken from ``second``."""
        child = np.array(first, dtype=np.float64, copy=True)
        w1, b1, w2, _ = _split(child, self.settings.nca.hidden)
        o1, c1, o2, _ = _split(np.asarray(second, dtype=np.float64), self.settings.nca.hidden)
        neuron = int(rng.integers(self.settings.nca.hidden))
        w1[:, neuron], b1[neuron], w2[neuron, :] = o1[:, neuron], c1[neuron], o2[neuron, :]
        return child

    def nca(self, genome: Any) -> LocalNCA:
        """The network a genome stands for, with this problem's NCA settings (``run.problem.nca(run.best_genome())``)."""
        return LocalNCA(np.asarray(genome, dtype=np.float64), self.settings.nca)

    def structure_of(self, genome: Any) -> Structure:
        """The structure a genome grows (the same as during evaluation)."""
        return grow(np.asarray(genome, dtype=np.float64), self.settings.nca)

    def write_artifacts(self, genome: Any, folder: Path) -> list[Path]:
        from structgen.domains.structures.render import render_check

        structure = self.structure_of(genome)
        report = self.judge(structure)
        structure = structure.with_metadata(score=report.score, integrity=report.integrity, height=report.height)
        paths = [structure.save(folder / "structure.json"), structure.export(folder / "structure.glb")]
        paths.append(atomic_write(folder / "report.json", json.dumps(report.to_dict(), indent=1) + "\n"))
        # A best written earlier in the run may have left its simulation here; it would be taken for this one's.
        (folder / "simulation.json").unlink(missing_ok=True)
        shown = report
        if report.method == "statics" and report.intact:
            # The static analysis chose this candidate and says it stands; the picture shows what the simulation
            # makes of it (when the simulation takes it), so a prediction the physics would not bear out is seen at
            # once. At most 5 simulated seconds: the faithful preset's 30 s horizon would make each picture cost more
            # than a generation; a structure that has not fallen by then is shown as it is.
            physics = self.settings.physics
            simulated = check_stability(structure, physics.replace(horizon=min(physics.horizon, 5.0)), errors="report")
            if simulated.error is None:
                paths.append(atomic_write(folder / "simulation.json", json.dumps(simulated.to_dict(), indent=1) + "\n"))
                shown = simulated
        if shown.error is None:
            paths.append(render_check(shown, folder / "structure.png"))
        return paths
