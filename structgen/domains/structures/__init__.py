"""The paper's domain: 3D lattice structures grown by a local NCA and judged by rigid-body physics.

- :mod:`.problem`: the settings (``[problem]``: evaluator, ``[problem.nca]``, ``[problem.physics]``) and the problem
  that grows NCA weights into structures and scores them with the paper's Q.
- :mod:`.commands`: the verbs ``grow``, ``evaluate``, ``show``, ``teach`` and ``tall`` (also at the top level:
  ``structgen grow`` is ``structgen structures grow``), what the generic ``info`` says of a structure file or a tall
  search, and the export of structure files and run elites as meshes.

This file only describes the domain (:data:`DOMAIN`); the problem loads, with torch and the physics, on first use.
"""

from typing import TYPE_CHECKING, Any

from structgen.registry import DomainSpec, MainJob

if TYPE_CHECKING:
    from structgen.domains.structures.problem import EVALUATORS, StableStructures, StructuresSettings

__all__ = ["DOMAIN", "EVALUATORS", "StableStructures", "StructuresSettings"]

DOMAIN = DomainSpec(
    id="structures-v0",
    entry_point="structgen.domains.structures.problem:StableStructures",
    settings="structgen.domains.structures.problem:StructuresSettings",
    summary="3D lattice structures grown by a local NCA and judged by rigid-body physics (the paper's Q)",
    commands="structgen.domains.structures.commands:COMMANDS",
    shortcuts=("grow", "evaluate", "show", "teach", "tall", "regrow", "design", "design-library"),
    aliases=("structures",),
    libraries=("torch", "pybullet", "trimesh"),
    # The paper's setup with its special rules (its local NCA, five steps, activation cutoff 0.6, no building below
    # the seed, the elitist GA keeping a fifth of the population), judged by the static analysis so that 200
    # generations of 40 take well under two minutes on two cores; the NCA's vertex cap of 64 (the domain's default).
    # With seed 0 its best structure (generation 144) is four vertices tall and stands under the faithful preset
    # (README, "Quick start"). Writing the best's files simulates it for the picture (about 8 s on a slow day) and
    # each plot costs most of a second, so both happen every 50 generations, not every 10.
    main_job=MainJob(
        run={"generations": 200, "seed": 0, "checkpoint_every": 50, "plot_every": 50},
        problem={"evaluator": "statics", "physics": {"preset": "faithful"}, "nca": {"cutoff": 0.6, "build_down": False}},
        optimizer="ga",
        optimizers={
            "ga": {"population": 40, "parents": 8},
            "cma_es": {"population": 40},
            "map_elites": {"batch_size": 40, "cells": [11, 32]},
            "cma_mae": {"emitters": 4, "batch_size": 10, "cells": [11, 32]},
        },
    ),
    test_settings={"nca": {"hidden": 8, "max_vertices": 16}},
)


def __getattr__(name: str) -> Any:
    # Names scripts used when this domain was one module; loading them loads torch and the physics.
    if name in ("EVALUATORS", "StableStructures", "StructuresSettings"):
        from structgen.domains.structures import problem

        return getattr(problem, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
