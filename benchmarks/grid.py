"""Speed of the 2D layout domains: batched conv NCA growth and HiGHS repair, beside the original's recorded times.

    python benchmarks/grid.py [--device cuda] [--skip-repair]

Prints a table. Growth: a population of 50 random NCAs (normal, sd 0.2 and 1.0) grown at 33x36 for 50 steps and
at 101x102 for 200 steps, median of 3 (genomes that settle stop early: the steps column says how many ran); on
another device (``--device cuda``) the layouts are also compared with the CPU's, tile for tile. Repair: the original's unrepaired 33x36 maps (shipped in ../shared/data/warehouse-maps)
repaired with the original's 60 s limit (every pair of unrepaired and repaired map it ships), its 101x102 ones
and a random NCA's 101x102 layout with a 120 s limit (greedy start). Every repaired map is checked by the
independent validity checker.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from structgen.domains.layouts.commands import AUTO_YES_NO
from structgen.domains.layouts.conv_nca import ConvNCA
from structgen.domains.layouts.grid import Grid
from structgen.domains.layouts.kinds import MANUFACTURING, WAREHOUSE, reference_maps
from structgen.domains.layouts.measures import violations
from structgen.domains.layouts.repair import repair

MAPS = reference_maps() or Path("no reference maps")
OURS = MAPS / "warehouse" / "ours"
MANUFACTURE = MAPS / "manufacture" / "ours"
# Every unrepaired map the original ships beside its repaired map (the pair gives the recorded Hamming distance),
# with the original's time limit: 60 s up to 33x36, and our goal of 120 s at 101x102 (the original allowed hours).
# (kind, unrepaired file, repaired file, seconds, manufacturing agents)
REPAIRS = [
    ("warehouse", "report/search_all/unrepaired.json", "report/search_all/repaired.json", 60, 0),
    ("warehouse", "report/nca_example/kiva_small_w_unrepaired.json", "report/nca_example/kiva_small_w_repaired.json", 60, 0),
    (
        "warehouse",
        "report/nca_example/bad/kiva_small_w_bad_unrepaired.json",
        "report/nca_example/bad/kiva_small_w_bad_repaired.json",
        60,
        0,
    ),
    (
        "warehouse",
        "report/nca_example/bad/kiva_small_w_bad_unrepaired2.json",
        "report/nca_example/bad/kiva_small_w_bad_repaired2.json",
        60,
        0,
    ),
    ("warehouse", "ours/kiva_small_60_agents_opt_unrepaired.json", "ours/kiva_small_60_agents_opt.json", 60, 0),
    (
        "warehouse",
        "ours/nca_to_show/cma_mae/medium_s_train/kiva_mid_cma-mae_entropy_throughput_hamming_a=5_s_train_mid_unrepaired.json",
        None,
        60,
        0,
    ),
    (
        "warehouse",
        "ours/nca_to_show/cma_mae/kiva_large_200_agents_cma-mae_opt_entropy_throughput_hamming_a=5_unrepaired.json",
        None,
        60,
        0,
    ),
    (
        "warehouse",
        "ours/nca_to_show/cma_mae/kiva_large_200_agents_cma-mae_opt_entropy_uneven_throughput_hamming_a=5_unrepaired.json",
        None,
        60,
        0,
    ),
    (
        "warehouse",
        "ours/nca_to_show/cma_mae/medium_s_train/kiva_large_cma-mae_entropy_throughput_hamming_a=5_s_train_mid_unrepaired.json",
        None,
        60,
        0,
    ),
    ("manufacturing", "nca_to_show/manufacture_large_200_agents_cma-mae_opt_alpha=5_sw=5_unrepaired.json", None, 60, 200),
    (
        "manufacturing",
        "nca_to_show/manufacture_large_200_agents_cma-mae_idx_0=15_opt_alpha=5_sw=5_unrepaired.json",
        None,
        60,
        200,
    ),
    (
        "warehouse",
        "ours/nca_to_show/xxlarge_maps/iter=50/kiva_xxlarge_cma-mae_global_opt_unrepaired.json",
        "ours/nca_to_show/xxlarge_maps/iter=50/kiva_xxlarge_cma-mae_global_opt_repaired.json",
        120,
        0,
    ),
    (
        "warehouse",
        "ours/nca_to_show/cma_mae/medium_s_train/kiva_xxlarge_cma-mae_entropy_throughput_hamming_a=5_s_train_mid_unrepaired.json",
        None,
        120,
        0,
    ),
    (
        "manufacturing",
        "xxlarge/manufacture_xxlarge_cma-mae_global_opt_unrepaired_one_endpt_throughput-hamming_a=5_sw=5_iter=200.json",
        "xxlarge/manufacture_xxlarge_cma-mae_global_opt_repaired_one_endpt_throughput-hamming_a=5_sw=5_iter=200.json",
        120,
        60,
    ),
]


def growth(device: str | None) -> list[str]:
    nca = ConvNCA(3)
    rows = []
    # sd 0.2 is where the paper's search starts (such genomes settle and stop early); 1.0 is chaotic (every step runs)
    for scale in (0.2, 1.0):
        genomes = np.random.default_rng(0).normal(0, scale, (50, nca.n_params))
        for name, iterations in (("33x36", 50), ("101x102", 200)):
            seed = WAREHOUSE.seed(WAREHOUSE.size(name).grown)
            nca.grow(genomes[:2], seed, 2, device)  # warm up
            times = []
            for _ in range(3):
                started = time.perf_counter()
                _, ran = nca.grow(genomes, seed, iterations, device, return_steps=True)
                times.append(time.perf_counter() - started)
            where = device or "cpu"
            if where != "cpu":  # the batched engine must grow the same layouts on every device
                on_device = nca.grow(genomes, seed, iterations, device)
                differ = int((on_device != nca.grow(genomes, seed, iterations, "cpu")).any(axis=(1, 2)).sum())
                where += ", same layouts as the CPU" if differ == 0 else f", {differ} of 50 layouts differ from the CPU's"
            rows.append(
                f"| grow 50 layouts (sd {scale}) | {name} | {iterations} steps, {ran.mean():.0f} run on average | {where} "
                f"| {statistics.median(times):.2f} s |"
            )
    return rows


def repairs(round_relaxation: bool | None) -> Iterator[str]:
    """Table rows, one as each repair finishes (the whole table takes about ten minutes)."""
    for kind_name, name, repaired_name, limit, agents in REPAIRS:
        kind = WAREHOUSE if kind_name == "warehouse" else MANUFACTURING
        folder = MAPS / "warehouse" if kind is WAREHOUSE else MANUFACTURE
        path = folder / name
        unrepaired = Grid.load(path, kind.vocabulary)
        recorded = Grid.load(folder / (repaired_name or name.replace("_unrepaired", "")), kind.vocabulary)
        hamming = int((unrepaired.tiles != recorded.tiles).sum())
        if kind is WAREHOUSE:  # the shelf count the original repaired to
            kwargs = {"shelves": int((recorded.tiles == kind.vocabulary.index("@")).sum())}
        else:
            kwargs = {"agents": agents}
        result = repair(unrepaired.tiles, kind, time_limit=limit, round_relaxation=round_relaxation, **kwargs)
        assert not violations(result.tiles, kind, fixed=unrepaired.tiles if kind is WAREHOUSE else None, **kwargs)
        original = recorded.metadata.get("milp_runtime")
        original_time = f"{original:.0f} s" if original else "time not recorded"
        short = name.removesuffix(".json").replace("_unrepaired", "").replace("ours/nca_to_show/", "")
        yield (
            f"| repair {kind_name} `{short}` | {unrepaired.shape[0]}x{unrepaired.shape[1]} | original {hamming} "
            f"({original_time}) | ours {result.hamming} ({result.method}, {_proof(result)}) | {result.seconds:.1f} s "
            f"(limit {limit} s) |"
        )
    nca = ConvNCA(3)
    genome = np.random.default_rng(1).normal(0, 0.2, nca.n_params)
    size = WAREHOUSE.size("101x102")
    tiles = WAREHOUSE.complete(nca.grow(genome, WAREHOUSE.seed(size.grown), size.iterations))
    result = repair(tiles, WAREHOUSE, shelves=2500, time_limit=120, round_relaxation=round_relaxation)
    assert not violations(result.tiles, WAREHOUSE, shelves=2500, fixed=tiles)
    yield (
        f"| repair warehouse, random NCA layout | 101x102 | original 70-3,326 s (CPLEX, 28 threads) | ours "
        f"{result.hamming} ({result.method}, {_proof(result)}) | {result.seconds:.1f} s (limit 120 s) |"
    )


def _proof(result) -> str:
    return "optimal" if result.optimal else result.gap_text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default=None, help="torch device for growth (default: the CPU)")
    parser.add_argument("--skip-repair", action="store_true", help="time growth only")
    parser.add_argument(
        "--round-relaxation",
        choices=tuple(AUTO_YES_NO),
        default="auto",
        help="round the linear relaxation before each repair's full search: auto (the repair's default), yes, no",
    )
    args = parser.parse_args()
    print(f"machine: {os.cpu_count()} cores, {platform.processor() or platform.machine()}; Python {platform.python_version()}")
    print("| what | size | work / original | device / ours | time |")
    print("|---|---|---|---|---|")
    for row in growth(args.device):
        print(row, flush=True)
    if not args.skip_repair:
        if not MAPS.is_dir():
            parser.error("the repair rows need the original's maps: set $STRUCTGEN_REFERENCE_MAPS to their folder")
        for row in repairs(AUTO_YES_NO[args.round_relaxation]):
            print(row, flush=True)


if __name__ == "__main__":
    main()
