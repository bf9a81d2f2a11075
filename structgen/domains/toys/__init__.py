"""The engine's two toy problems as domains: quick to evaluate, no physics, one per kind of genome.

``sphere-v0`` has flat float genomes (every optimiser runs it); ``ones-v0`` has tuples of bits with the problem's own
mutation and crossover (``ga`` and ``map_elites`` run it), the way rule sets and finite-state machines come. Both
are for trying optimisers and settings in seconds. The problems themselves are in :mod:`evolution.toys`.
"""

from structgen.registry import DomainSpec, MainJob

SPHERE = DomainSpec(
    id="sphere-v0",
    entry_point="evolution.toys:Sphere",
    settings="evolution.toys:SphereSettings",
    summary="toy: climb to a point in 8 dimensions (vector genomes, no physics)",
    aliases=("sphere",),
    main_job=MainJob(
        run={"generations": 30, "workers": 0},
        optimizers={"ga": {"population": 40, "parents": 8}, "cma_es": {"population": 16}},
    ),
)

ONES = DomainSpec(
    id="ones-v0",
    entry_point="evolution.toys:Ones",
    settings="evolution.toys:OnesSettings",
    summary="toy: count ones in a bit string (object genomes with their own mutation, no physics)",
    aliases=("ones",),
    main_job=MainJob(run={"generations": 30, "workers": 0}, optimizers={"ga": {"population": 40, "parents": 8}}),
)
