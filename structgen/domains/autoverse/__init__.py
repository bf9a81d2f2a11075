"""Autoverse: single-player grid games whose mechanics are rewrite rules, evolved so that a best-first search needs
many iterations to find their best play (Earle and Togelius).

- :mod:`.game`: a game as arrays (rules, rewards, map); random games and mutation;
- :mod:`.engine`: the batched engine (torch on GPU, the numba kernel of :mod:`._kernels` on CPU) and observations;
- :mod:`.search`: best-first search over many games at once;
- :mod:`.problem`: the evolution problem (fitness = iteration of the best return; growing budget; playtraces);
- :mod:`.show`: pictures and GIFs; :mod:`.commands`: ``play``, ``search``, ``clone``, ``show``.

This file only describes the domain; torch loads on first use.
"""

from structgen.registry import DomainSpec, MainJob

AUTOVERSE = DomainSpec(
    id="autoverse-v0",
    entry_point="structgen.domains.autoverse.problem:AutoverseProblem",
    settings="structgen.domains.autoverse.problem:AutoverseSettings",
    summary="grid games of rewrite rules, evolved so that best-first search needs many iterations to play them best",
    commands="structgen.domains.autoverse.commands:AUTOVERSE_COMMANDS",
    kernels="structgen.domains.autoverse.engine:compile_kernels",
    libraries=("torch",),
    # The original's (40 + 40) loop with its budget of 200, for 10 generations in one process (the engine batches
    # the 40 searches; worker processes would only split the batch); the budget reaches about 2,000 by then.
    main_job=MainJob(
        run={"generations": 10, "seed": 0, "workers": 0},
        optimizer="ga",
        optimizers={"ga": {"population": 80, "parents": 40, "initial": 40}},
    ),
    test_settings={"budget": 15, "budget_step": 15},
)
