"""The layout family: the warehouse paper's 2D domains, warehouses, manufacturing floors and mazes, grown by a conv NCA.

What the three share sits here:

- :mod:`.grid` (the layout file format), :mod:`.conv_nca` (the generator) and :mod:`.kinds` (tiles, sizes, seed
  blocks and fixed parts of each kind);
- :mod:`.measures`: shelf components, pattern entropy, similarity, and the independent validity check;
- :mod:`.repair` and :mod:`.patch`: the fewest-changes repair as a MILP solved by HiGHS, and the cheap repairs;
- :mod:`.problem`: the three problems; :mod:`.commands` and :mod:`.show`: their verbs and pictures.

Each member's own machinery sits in its folder:

- :mod:`.warehouse` (warehouse and manufacturing floors): :mod:`.warehouse.simulator`, robots fetching goals,
  with the compiled planners :mod:`.warehouse._mapf`, :mod:`.warehouse._pbs` and :mod:`.warehouse._steps`;
- :mod:`.maze`: :mod:`.maze.walkers` (start and goal, scripted agents), :mod:`.maze.env` (the batched environment),
  :mod:`.maze.agent` and :mod:`.maze.training` (the learned agent), :mod:`.maze.experiment` (the paper's).

This file only describes the domains; torch, HiGHS and numba load on first use.
"""

from structgen.registry import DomainSpec, MainJob

_PACKAGE = "structgen.domains.layouts"

# The main job of each: the original's CMA-MAE shape (5 emitters of 10, sigma0 0.2) for a few generations.
_CMA_MAE = {"cma_mae": {"emitters": 5, "batch_size": 10, "sigma0": 0.2, "cells": [100, 100]}}
# An evaluation repairs and simulates: layouts far from valid go to the greedy repair (repair_greedy_beyond), and
# HiGHS's bounded search (repair_search) takes the rest, so the job repeats exactly; two generations, about 2 minutes
# on 2 cores.
_REPAIRED_MAIN = MainJob(run={"generations": 2, "seed": 0}, optimizer="cma_mae", optimizers=_CMA_MAE)

WAREHOUSE = DomainSpec(
    id="warehouse-v0",
    kernels=f"{_PACKAGE}.warehouse.simulator:compile_kernels",
    entry_point=f"{_PACKAGE}.problem:LayoutProblem",
    settings=f"{_PACKAGE}.problem:WarehouseSettings",
    summary="warehouse layouts grown by a conv NCA, repaired by a MILP, scored by simulated robots' throughput",
    commands=f"{_PACKAGE}.commands:WAREHOUSE_COMMANDS",
    libraries=("torch", "highspy", "numba"),
    main_job=_REPAIRED_MAIN,
    test_settings={
        "size": "6x8",
        "shelves": 6,
        "iterations": 5,
        "hidden": 8,
        "repair_node_limit": 50,
        "agents": 4,
        "simulations": 2,
        "simulation_steps": 30,
    },
)

MANUFACTURING = DomainSpec(
    id="manufacturing-v0",
    kernels=f"{_PACKAGE}.warehouse.simulator:compile_kernels",
    entry_point=f"{_PACKAGE}.problem:LayoutProblem",
    settings=f"{_PACKAGE}.problem:ManufacturingSettings",
    summary="manufacturing floors (three station kinds) grown by a conv NCA, repaired by a MILP, scored by robots' throughput",
    commands=f"{_PACKAGE}.commands:MANUFACTURING_COMMANDS",
    libraries=("torch", "highspy", "numba"),
    main_job=_REPAIRED_MAIN,
    # HiGHS spends most of a second on the root of even a 5x6 floor's repair; 4x4 keeps an evaluation of 4 near one.
    test_settings={
        "size": "4x4",
        "iterations": 5,
        "hidden": 8,
        "agents": 1,
        "repair_node_limit": 1,
        "simulations": 2,
        "simulation_steps": 30,
    },
)

MAZE = DomainSpec(
    id="maze-v0",
    kernels=f"{_PACKAGE}.maze.way_on:compile_kernels",
    entry_point=f"{_PACKAGE}.problem:LayoutProblem",
    settings=f"{_PACKAGE}.problem:MazeSettings",
    summary="mazes grown by a conv NCA, walked by a learned agent (objective: solvable)",
    commands=f"{_PACKAGE}.commands:MAZE_COMMANDS",
    libraries=("torch", "numba"),
    main_job=MainJob(
        run={"generations": 10, "seed": 0},
        optimizer="cma_mae",
        optimizers={"cma_mae": {"emitters": 5, "batch_size": 30, "sigma0": 0.2, "cells": [100, 162]}},
    ),
    test_settings={"size": "8x8", "iterations": 5, "hidden": 8, "episodes": 2},
)
