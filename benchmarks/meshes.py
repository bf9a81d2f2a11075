"""Mesh export: file sizes and times of GLB (shared geometry), STL and the watertight --solid shell, by structure size.

    python benchmarks/meshes.py [--sizes 64 500 2000]

Structures are grown by random NCAs (seed 3, the paper's network) with the vertex cap set to each size, so they are
dense blobs: the most edges per vertex a growth makes. Prints a markdown table and the machine it ran on.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import trimesh  # noqa: E402

from structgen import LocalNCA, NCAConfig  # noqa: E402


def timed_export(structure, path: Path, **options) -> tuple[float, Path]:
    started = time.perf_counter()
    written = structure.export(path, **options)
    return time.perf_counter() - started, written


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 500, 2000], help="vertex caps of the structures")
    parser.add_argument("--solid-up-to", type=int, default=600, help="make --solid shells only up to this many vertices")
    args = parser.parse_args()
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "?")
    print(f"machine: {cpu}, {os.cpu_count()} CPUs; Python {platform.python_version()}, trimesh {trimesh.__version__}\n")
    print("| vertices | edges | GLB | GLB time | STL | STL time | solid STL | solid time | watertight |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch)
        for size in args.sizes:
            structure = LocalNCA.random(3, NCAConfig(iterations=8, max_vertices=size)).grow()
            glb_s, glb = timed_export(structure, folder / "s.glb")
            stl_s, stl = timed_export(structure, folder / "s.stl")
            row = [
                f"{structure.n_vertices:,}",
                f"{structure.n_edges:,}",
                f"{glb.stat().st_size / 1e3:,.0f} KB",
                f"{glb_s:.2f} s",
                f"{stl.stat().st_size / 1e6:,.1f} MB",
                f"{stl_s:.2f} s",
            ]
            if structure.n_vertices <= args.solid_up_to:
                solid_s, solid = timed_export(structure, folder / "solid.stl", solid=True)
                shell = trimesh.load(solid)
                row += [f"{solid.stat().st_size / 1e6:,.1f} MB", f"{solid_s:.1f} s", "yes" if shell.is_watertight else "no"]
            else:
                row += ["-", "-", "-"]
            print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
