"""The paper's maze experiment for maze agents trained with different seeds: each row's mean and spread over seeds.

    python benchmarks/maze_agent_seeds.py [WEIGHTS ...] [--results PREFIX]

Runs ``structgen maze experiment`` on the paper's own grown mazes (18x18 and 66x66, reference data:
$STRUCTGEN_REFERENCE_DATA) with each agent (default: the shipped agent, training seed 0, and
``docs/maze_agent_seed1.pt``, ``docs/maze_agent_seed2.pt``, made by ``structgen maze train --seed 1`` and ``--seed 2``
with the shipped agent's settings, about 23 minutes each on 2 cores) and prints each row's success rate per agent
and its mean and standard error over the agents, beside the paper's ACCEL agent. ``--results PREFIX`` writes
PREFIX.json and PREFIX.md. About 3 minutes an agent on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from evolution.files import write_table  # noqa: E402
from evolution.stats import mean_and_standard_error  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
AGENTS = ["docs/maze_agent.pt", "docs/maze_agent_seed1.pt", "docs/maze_agent_seed2.pt"]
MAZES = "maze/ours/nca_to_show"  # inside the reference data's warehouse-maps/
PAPER = {"grown small": 0.90, "grown large": 0.93, "baselines": 0.22}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("weights", nargs="*", default=AGENTS, help="agent weights files (default the three shipped seeds)")
    parser.add_argument("--results", type=Path, default=None, metavar="PREFIX", help="also write PREFIX.json and .md")
    args = parser.parse_args()
    from structgen.domains.layouts.kinds import reference_maps

    maps = reference_maps()
    if maps is None:
        raise SystemExit("the paper's grown mazes are reference data: set $STRUCTGEN_REFERENCE_DATA (see README)")
    small, large = (maps / MAZES / f"maze_{size}_nca_100_50.json" for size in ("small", "xxlarge"))
    runs = {}
    for weights in args.weights:
        command = [sys.executable, "-m", "structgen", "maze", "experiment", "--small", str(small), "--large", str(large),
                   "--weights", str(weights), "--json"]  # fmt: skip
        done = subprocess.run(command, capture_output=True, text=True, check=True, cwd=ROOT)
        runs[str(weights)] = {row["name"]: row for row in json.loads(done.stdout)["rows"]}
        print(f"{weights}: " + ", ".join(f"{n} {r['success_rate']:.1%}" for n, r in runs[str(weights)].items()), flush=True)
    lines = [f"The paper's grown mazes (`warehouse-maps/{MAZES}/maze_small_nca_100_50.json`, `maze_xxlarge_nca_100_50.json`), "
             f"{len(runs)} agents; {platform.processor() or platform.machine()}, {time.strftime('%Y-%m-%d')}.", "",
             "| maze | " + " | ".join(f"`{Path(w).name}`" for w in runs) + " | mean ± s.e. over agents | paper (ACCEL) |",
             "|---|" + "---:|" * (len(runs) + 2)]  # fmt: skip
    report: dict = {"agents": list(runs), "mazes": [f"warehouse-maps/{MAZES}/{p.name}" for p in (small, large)], "rows": {}}
    for name, paper in PAPER.items():
        rates = [run[name]["success_rate"] for run in runs.values()]
        mean, error = mean_and_standard_error(rates)
        report["rows"][name] = {"success_rates": rates, "mean": mean, "standard_error": error, "paper": paper}
        lines.append(f"| {name} | " + " | ".join(f"{r:.1%}" for r in rates) + f" | {mean:.1%} ± {error:.1%} | {paper:.0%} |")
    text = "\n".join(lines)
    print(text)
    if args.results is not None:
        write_table(args.results, report, text + "\n")


if __name__ == "__main__":
    main()
