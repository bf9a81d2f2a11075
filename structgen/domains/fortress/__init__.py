"""The Amorphous Fortress: worlds of entities each driven by a finite-state machine, illuminated with MAP-Elites for
worlds whose machines are well explored (Charity, Rajesh, Earle, Togelius; QD follow-up by Earle et al.).

- :mod:`.formats`: the original's text formats (entity classes, fortress files, saved elites), read and written;
- :mod:`.engine`: many worlds under many seeds stepped together (the numba kernel of :mod:`._kernels`);
- :mod:`.world`: random worlds and the original's mutation operators;
- :mod:`.problem`: the evolution problem (fitness = share of machines visited; measures: entities, nodes or entropy);
- :mod:`.robustness`: archives re-evaluated on new seeds and longer episodes;
- :mod:`.show`: maps, GIFs, population plots; :mod:`.commands`: ``run``, ``replay``, ``show``, ``robustness``.

This file only describes the domain; numba loads on first use.
"""

from structgen.registry import DomainSpec, MainJob

_PACKAGE = "structgen.domains.fortress"

FORTRESS = DomainSpec(
    id="fortress-v0",
    entry_point=f"{_PACKAGE}.problem:FortressProblem",
    settings=f"{_PACKAGE}.problem:FortressSettings",
    summary="worlds of FSM-driven entities, illuminated with MAP-Elites for machines that their simulations explore",
    commands=f"{_PACKAGE}.commands:FORTRESS_COMMANDS",
    kernels=f"{_PACKAGE}.world:compile_kernels",
    libraries=("numba",),
    # The original's MAP-Elites (100 x 100 cells, 9 mutants and 1 random world a generation, 5 simulations of 100
    # ticks each) for 1,000 of its 10,000 generations, in one process (the engine runs the 50 simulations of a
    # generation on numba's threads).
    main_job=MainJob(
        run={"generations": 1000, "seed": 0, "workers": 0, "checkpoint_every": 100, "plot_every": 100},
        optimizer="map_elites",
        optimizers={"map_elites": {"cells": [100, 100], "batch_size": 10, "immigrants": 1}},
    ),
    test_settings={"steps": 20, "sims": 2},
)
