"""How long a command takes from start to finish when it has little to do: the cost of starting Python, importing
structgen and building the command line (every registered domain's verbs included).

    python benchmarks/startup.py [--repeats 7]

Each command runs in a fresh process (median wall time over repeats). Domains are described by strings and load on
first use, so commands that need no engine should not pay for torch, PyBullet or pyribs; `import torch` alone is
timed for comparison.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

STRUCTURE = '{"vertices": [[0, 0, 0], [0, 0, 1]], "edges": [[0, 1]]}'


def median_seconds(argv: list[str], repeats: int, cwd: str) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        subprocess.run(argv, cwd=cwd, check=True, capture_output=True)
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=7, help="runs of each command (default 7)")
    args = parser.parse_args()
    structgen = [sys.executable, "-m", "structgen"]
    rows = {
        "python -c pass": [sys.executable, "-c", "pass"],
        "python -c 'import torch' (for comparison)": [sys.executable, "-c", "import torch"],
        "structgen --help": [*structgen, "--help"],
        "structgen list domains": [*structgen, "list", "domains"],
        "structgen info s.json": [*structgen, "info", "s.json"],
        "structgen evolve --print-config (loads the domain: torch, physics)": [*structgen, "evolve", "--print-config"],
    }
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "?")
    print(f"machine: {cpu}, {os.cpu_count()} cores; Python {platform.python_version()}\n")
    print("| command | median wall s |")
    print("|---|---|")
    with tempfile.TemporaryDirectory() as scratch:
        Path(scratch, "s.json").write_text(STRUCTURE)
        for name, argv in rows.items():
            print(f"| `{name}` | {median_seconds(argv, args.repeats, scratch):.2f} |", flush=True)


if __name__ == "__main__":
    main()
