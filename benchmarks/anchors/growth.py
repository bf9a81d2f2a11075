"""Layout growth: our conv NCA beside the warehouse paper's own network, timed in alternation on the same work.

    python benchmarks/anchors/growth.py [--original PATH] [--threads 1] [--repeats 5] [--genomes 50]
                                        [--scales 0.2 1.0] [--size 101x102]

Both grow the same genomes (normal, mean 0, the given standard deviations: 0.2 is where the paper's search starts,
1.0 is far out, where growth is chaotic) from the same seed block for the same steps (200 at 101x102, 50 at
33x36): the original one genome at a time, as its evaluation does (``set_params`` then ``generate``), ours as one
call for the whole population. Each repeat times the original and then ours, in one process on the same thread
count; the table gives the median of the repeats, the ratio of the medians, and how many layouts the two grew
alike tile for tile (chaotic genomes amplify float rounding, so two correct implementations part there).

The original is ``lunjohnzhang/warehouse_env_gen_nca_public``: pass a checkout with ``--original``, or the script
clones it into a scratch folder (network needed). Its module imports ``gin``: install ``structgen[anchors]``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# Run as a script, this file's folder comes first on sys.path; the repository root must be importable instead.
ROOT = Path(__file__).resolve().parents[2]
sys.path = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from benchmarks.anchors._original import checkout_of_original, import_from_original  # noqa: E402
from structgen.domains.layouts.conv_nca import ConvNCA  # noqa: E402
from structgen.domains.layouts.kinds import WAREHOUSE  # noqa: E402

REPOSITORY = "https://github.com/lunjohnzhang/warehouse_env_gen_nca_public"
STEPS = {"33x36": 50, "101x102": 200}


def original_network(checkout: Path):
    """The original's ``WarehouseNCA`` class, imported from a checkout of its repository."""
    return import_from_original(checkout, "env_search.warehouse.generator.nca_generator").WarehouseNCA


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--original", type=Path, help="a checkout of the original repository (default: clone it)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads for both (default 1)")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs of each; the median is shown (default 5)")
    parser.add_argument("--genomes", type=int, default=50, help="genomes grown per run (default 50)")
    parser.add_argument("--scales", type=float, nargs="+", default=[0.2, 1.0], help="genome standard deviations")
    parser.add_argument("--size", choices=list(STEPS), default="101x102", help="map size (default 101x102)")
    args = parser.parse_args()
    import torch

    torch.set_num_threads(args.threads)
    with tempfile.TemporaryDirectory(prefix="structgen-anchor-") as scratch:
        network = original_network(checkout_of_original(args.original, Path(scratch), REPOSITORY, ("env_search",)))
        original = network(nc=3, n_aux_chan=0, kernel_size=3, n_hid_chan=32)
        ours = ConvNCA(3)
        seed = WAREHOUSE.seed(WAREHOUSE.size(args.size).grown)
        steps = STEPS[args.size]

        def grow_original(genomes: np.ndarray) -> np.ndarray:
            layouts = []
            for genome in genomes:
                original.set_params(genome)
                layout, _ = original.generate(torch.as_tensor(seed[None], dtype=torch.int64), steps)
                layouts.append(layout[0].numpy())
            return np.array(layouts, dtype=np.uint8)

        print(
            f"growth of {args.genomes} layouts at {args.size}, {steps} steps, {args.threads} thread(s), "
            f"median of {args.repeats} runs in alternation"
        )
        print("| genomes (sd) | original s/layout | ours s/layout | speed-up | same layouts | our mean steps run |")
        print("|---|---:|---:|---:|---:|---:|")
        for scale in args.scales:
            genomes = np.random.default_rng(0).normal(0, scale, (args.genomes, ours.n_params)).astype(np.float32)
            grow_original(genomes[:1]), ours.grow(genomes[:1], seed, 2)  # warm up both
            times: dict[str, list[float]] = {"original": [], "ours": []}
            for _ in range(args.repeats):
                began = time.perf_counter()
                theirs = grow_original(genomes)
                times["original"].append(time.perf_counter() - began)
                began = time.perf_counter()
                mine, ran = ours.grow(genomes, seed, steps, return_steps=True)
                times["ours"].append(time.perf_counter() - began)
            theirs_s, ours_s = (statistics.median(times[k]) / args.genomes for k in ("original", "ours"))
            same = int((theirs == mine).all(axis=(1, 2)).sum())
            print(
                f"| {scale} | {theirs_s:.3f} | {ours_s:.3f} | {theirs_s / ours_s:.1f}x | {same} of {args.genomes} | "
                f"{ran.mean():.0f} of {steps} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
