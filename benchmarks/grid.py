"""Speed of the 2D layout domains: batched conv NCA growth and HiGHS repair, beside the original's recorded times.

    python benchmarks/grid.py [--device cuda] [--skip-repair]

Prints a table. Growth: a population of 50 random NCAs (normal, sd 0.2) grown at 33x36 for 50 steps and at
101x102 for 200 steps. Repair: the original's unrepaired 33x36 maps (shipped in ../shared/data/warehouse-maps)
repaired with a 60 s limit, and a random NCA's 101x102 layout with a 120 s limit (greedy start).
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from structgen.conv_nca import ConvNCA
from structgen.domains.warehouse.layouts import MANUFACTURING, WAREHOUSE
from structgen.domains.warehouse.measures import violations
from structgen.domains.warehouse.repair import repair
from structgen.grid import Grid

MAPS = Path(__file__).resolve().parents[2] / "shared" / "data" / "warehouse-maps"
OURS = MAPS / "warehouse" / "ours" / "nca_to_show" / "cma_mae"
REPAIRS = [
    ("warehouse", OURS / "kiva_large_200_agents_cma-mae_opt_entropy_throughput_hamming_a=5_unrepaired.json", 240),
    ("warehouse", OURS / "kiva_large_200_agents_cma-mae_opt_entropy_uneven_throughput_hamming_a=5_unrepaired.json", 240),
    ("warehouse", OURS / "medium_s_train/kiva_large_cma-mae_entropy_throughput_hamming_a=5_s_train_mid_unrepaired.json", 240),
    ("warehouse", OURS / "medium_s_train/kiva_mid_cma-mae_entropy_throughput_hamming_a=5_s_train_mid_unrepaired.json", 40),
    (
        "manufacturing",
        MAPS / "manufacture/ours/nca_to_show/manufacture_large_200_agents_cma-mae_opt_alpha=5_sw=5_unrepaired.json",
        200,
    ),
]


def growth(device: str | None) -> list[str]:
    nca = ConvNCA(3)
    genomes = np.random.default_rng(0).normal(0, 0.2, (50, nca.n_params))
    rows = []
    for name, iterations in (("33x36", 50), ("101x102", 200)):
        seed = WAREHOUSE.seed(WAREHOUSE.size(name).grown)
        nca.grow(genomes[:2], seed, 2, device)  # warm up
        times = []
        for _ in range(3):
            started = time.perf_counter()
            nca.grow(genomes, seed, iterations, device)
            times.append(time.perf_counter() - started)
        rows.append(f"| grow 50 layouts | {name} | {iterations} steps | {device or 'cpu'} | {min(times):.2f} s | |")
    return rows


def repairs() -> list[str]:
    rows = []
    for kind_name, path, count in REPAIRS:
        kind = WAREHOUSE if kind_name == "warehouse" else MANUFACTURING
        unrepaired = Grid.load(path, kind.vocabulary)
        recorded = Grid.load(str(path).replace("_unrepaired", ""), kind.vocabulary)
        hamming = int((unrepaired.tiles != recorded.tiles).sum())
        kwargs = {"shelves": count} if kind is WAREHOUSE else {"agents": count}
        result = repair(unrepaired.tiles, kind, time_limit=60, **kwargs)
        assert not violations(result.tiles, kind, fixed=unrepaired.tiles if kind is WAREHOUSE else None, **kwargs)
        proof = "optimal" if result.optimal else f"gap {result.gap:.1%}"
        original = recorded.metadata.get("milp_runtime")
        original_time = f"{original:.0f} s" if original else "time not recorded"
        rows.append(
            f"| repair {path.name[:48]} | {unrepaired.shape[0]}x{unrepaired.shape[1]} | original {hamming} "
            f"({original_time}) | ours {result.hamming}, {proof} | "
            f"{result.seconds:.1f} s | |"
        )
    nca = ConvNCA(3)
    genome = np.random.default_rng(1).normal(0, 0.2, nca.n_params)
    size = WAREHOUSE.size("101x102")
    tiles = WAREHOUSE.complete(nca.grow(genome, WAREHOUSE.seed(size.grown), size.iterations))
    result = repair(tiles, WAREHOUSE, shelves=2500, time_limit=120)
    rows.append(
        f"| repair random NCA layout | 101x102 | original 70-3,326 s (CPLEX, 28 threads) | ours {result.hamming} "
        f"({result.method}, {'optimal' if result.optimal else f'gap {result.gap:.1%}'}) | {result.seconds:.1f} s | |"
    )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", default=None, help="torch device for growth (default: the CPU)")
    parser.add_argument("--skip-repair", action="store_true", help="time growth only")
    args = parser.parse_args()
    print(f"machine: {os.cpu_count()} cores, {platform.processor() or platform.machine()}; Python {platform.python_version()}")
    print("| what | size | work | device / result | time | |")
    print("|---|---|---|---|---|---|")
    for row in growth(args.device):
        print(row, flush=True)
    if not args.skip_repair:
        for row in repairs():
            print(row, flush=True)


if __name__ == "__main__":
    main()
