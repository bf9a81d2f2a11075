"""RHCR, the warehouse paper's simulator, built from the authors' repository in a scratch folder and run beside `pbs`.

    python benchmarks/anchors/rhcr.py speed  [--original PATH] [--repeats 3]
    python benchmarks/anchors/rhcr.py rounds [--original PATH] [--agents 1500] [--steps 300] [--map NAME] [--uneven]
    python benchmarks/anchors/rhcr.py sweep  [--original PATH] [--robots 500,1000,...] [--steps 300] [--map NAME]
                                              [--uneven] [--output FILE.json]

``speed``: 200 robots x 1,000 steps on the paper's CMA-MAE 33x36 layout, seed 0, RHCR and ``pbs`` timed in
alternation (one process each, median of the repeats). ``rounds``: one run of RHCR with its per-round report on (the
outcome of each PBS call, its high-level nodes expanded and generated), printed as a table with the throughput, then
the same run with ``pbs`` (rounds it gave up on, nodes, children that could not be made consistent). ``sweep``: RHCR's
throughput at several robot counts on one map, written as JSON for ``benchmarks/throughput_vs_agents.py --rhcr``.
All use the paper's settings (PBS with SIPP, window 10, replanning every 5 steps, ``prioritize_start`` on unless
``--no-prioritize-start``, 60 s per PBS call, stop at a traffic jam); a map under ``manufacture/`` runs RHCR's
manufacturing scenario (three station kinds, tasks of 2, 5 and 10 steps), ``--uneven`` weighs the left
workstations five times.

The original is ``lunjohnzhang/warehouse_env_gen_nca_public`` (its ``RHCR/`` folder is the authors' fork of RHCR,
under a research-only licence): pass a checkout with ``--original`` or the script clones it. Nothing of it enters
this project: its sources are copied into ``--build-dir`` and compiled there with ``-O3`` into a Python module, after
two mechanical changes that let it build without Boost's compiled libraries (``std::filesystem`` for
``boost::filesystem``; an unused ``program_options`` alias dropped). Header-only Boost, pybind11 and nlohmann-json
come from PyPI (``boost-headers``, ``pybind11``, ``nlohmann-json``) into the build folder. Needs g++ with C++17 and
the reference maps (found as the tests find them, or ``$STRUCTGEN_REFERENCE_MAPS``).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path; the repository root must be importable instead.
ROOT = Path(__file__).resolve().parents[2]
sys.path = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from benchmarks.anchors._original import checkout_of_original  # noqa: E402

REPOSITORY = "https://github.com/lunjohnzhang/warehouse_env_gen_nca_public"
OURS = "warehouse/ours/nca_to_show"
SMALL = f"{OURS}/cma_mae/kiva_large_200_agents_cma-mae_opt_entropy_throughput_hamming_a=5.json"
LARGE = f"{OURS}/xxlarge_maps/iter=200/kiva_xxlarge_cma-mae_global_opt_repaired_one_endpt_throughput-hamming_a=5.json"
BUILD_PACKAGES = ("pybind11", "nlohmann-json", "boost-headers")
# What one round's report line holds: "PBS:Succeed,<seconds>,<expanded>,<generated>,...".
ROUND = re.compile(r"^PBS:(\w+),([\d.]+),(\d+),(\d+)")


def build(checkout: Path, build_dir: Path) -> Path:
    """The RHCR Python module compiled in ``build_dir`` (reused when it is there); returns the folder holding it."""
    source = checkout / "RHCR"
    module_dir = build_dir / "RHCR"
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    module = module_dir / f"warehouse_sim{suffix}"
    if module.exists():
        return module_dir
    if not (source / "src" / "WarehouseSimulation.cpp").exists():
        raise SystemExit(f"{checkout}: no RHCR/src/WarehouseSimulation.cpp (not a checkout of {REPOSITORY})")
    packages = build_dir / "packages"
    if not packages.exists():
        done = subprocess.run(
            [sys.executable, "-m", "pip", "install", "--quiet", "--target", str(packages), *BUILD_PACKAGES],
            capture_output=True, text=True,
        )  # fmt: skip
        if done.returncode:
            raise SystemExit(f"could not install {', '.join(BUILD_PACKAGES)}: {done.stderr.strip()}")
    shutil.rmtree(module_dir, ignore_errors=True)
    shutil.copytree(source, module_dir)
    for path in [*(module_dir / "src").glob("*.cpp"), *(module_dir / "inc").glob("*.h")]:
        text = path.read_text(encoding="utf-8", errors="surrogateescape")
        changed = text.replace("#include <boost/filesystem.hpp>", "#include <filesystem>")
        changed = changed.replace("boost::filesystem", "std::filesystem")
        changed = changed.replace("namespace po = boost::program_options;", "")
        changed = changed.replace("#include <boost/program_options.hpp>", "")
        if changed != text:
            path.write_text(changed, encoding="utf-8", errors="surrogateescape")
    includes = [
        module_dir / "inc",
        packages / "boost_headers" / "include",
        packages / "nlohmann_json" / "include",
        packages / "pybind11" / "include",
        Path(sysconfig.get_paths()["include"]),
    ]
    flags = ["-O3", "-DNDEBUG", "-std=c++17", "-fPIC", "-w"]
    # The sources lean on headers older compilers pulled in implicitly.
    flags += [f"-include{header}" for header in ("set", "algorithm", "climits", "cstring", "limits")]
    flags += [f"-I{path}" for path in includes]
    sources = [path for path in sorted((module_dir / "src").glob("*.cpp")) if path.name != "driver.cpp"]
    objects = []
    print(f"building RHCR in {module_dir} ({len(sources)} files) ...", flush=True)
    for path in sources:
        target = path.with_suffix(".o")
        done = subprocess.run(["g++", *flags, "-c", str(path), "-o", str(target)], capture_output=True, text=True)
        if done.returncode:
            raise SystemExit(f"g++ failed on {path.name}:\n{done.stderr[-2000:]}")
        objects.append(str(target))
    done = subprocess.run(["g++", "-shared", *objects, "-o", str(module)], capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"linking RHCR failed:\n{done.stderr[-2000:]}")
    return module_dir


def is_factory(map_file: Path) -> bool:
    return "manufacture" in map_file.parts


def run_rhcr(
    module_dir: Path, map_file: Path, agents: int, steps: int, seed: int, screen: int, prioritize_start: bool,
    uneven: bool = False,
):  # fmt: skip
    """One RHCR simulation in a fresh process (it prints to the C++ stdout); returns (result dict, stdout)."""
    scenario = "MANUFACTURE" if is_factory(map_file) else "KIVA"
    settings = dict(
        map=map_file.read_text(), output=str(module_dir.parent / "output"), scenario=scenario, task="", agentNum=agents,
        cutoffTime=60, screen=screen, solver="PBS", id=False, single_agent_solver="SIPP", lazyP=False,
        simulation_time=steps, simulation_window=5, travel_time_window=0, potential_function="NONE",
        potential_threshold=0, rotation=False, robust=0, CAT=False, hold_endpoints=False, dummy_paths=False,
        prioritize_start=prioritize_start, suboptimal_bound=1, log=False, test=False, force_new_logdir=False,
        save_result=False, save_solver=False, save_heuristics_table=False, stop_at_traffic_jam=True,
        left_w_weight=5.0 if uneven else 1.0, right_w_weight=1.0, planning_window=10, seed=seed,
    )  # fmt: skip
    if scenario == "MANUFACTURE":  # the paper's manufacturing configuration (config/manufacture/*.gin)
        settings.update(n_station_types=3, station_wait_times=[2, 5, 10])
    program = (
        "import json, sys; sys.path.insert(0, sys.argv[1]); import warehouse_sim; "
        "result = warehouse_sim.run(**json.loads(sys.stdin.read())); sys.stdout.flush(); "
        "open(sys.argv[2], 'w').write(result)"
    )
    result_file = module_dir.parent / "result.json"
    done = subprocess.run(
        [sys.executable, "-c", program, str(module_dir), str(result_file)],
        input=json.dumps(settings), capture_output=True, text=True,
    )  # fmt: skip
    if done.returncode:
        raise SystemExit(f"RHCR failed:\n{done.stderr[-2000:]}")
    return json.loads(result_file.read_text()), done.stdout


def run_ours(map_file: Path, agents: int, steps: int, seed: int, uneven: bool = False):
    from structgen.domains.layouts.grid import Grid
    from structgen.domains.layouts.kinds import MANUFACTURING, WAREHOUSE
    from structgen.domains.layouts.warehouse.simulator import simulate

    kind = MANUFACTURING if is_factory(map_file) else WAREHOUSE
    tiles = Grid.load(map_file, kind.vocabulary).tiles
    return simulate(tiles, agents, steps, kind=kind, seed=seed, planner="pbs", uneven=uneven)


def speed(module_dir: Path, maps: Path, repeats: int) -> None:
    map_file = maps / SMALL
    run_ours(map_file, 200, 50, 0)  # compile before timing
    theirs, ours = [], []
    for _ in range(repeats):
        result, _ = run_rhcr(module_dir, map_file, 200, 1000, 0, 0, True)
        theirs.append((result["cpu_runtime"], result["throughput"]))
        began = time.process_time()
        mine = run_ours(map_file, 200, 1000, 0)
        ours.append((time.process_time() - began, mine.throughput))
    print(f"\n200 robots x 1,000 steps, CMA-MAE 33x36, seed 0, median of {repeats}:\n")
    print("| simulator | CPU seconds | throughput |\n|---|---:|---:|")
    print(f"| RHCR (-O3, PBS + SIPP) | {statistics.median(t for t, _ in theirs):.2f} | {theirs[0][1]:.3f} |")
    print(f"| structgen `pbs` | {statistics.median(t for t, _ in ours):.2f} | {ours[0][1]:.3f} |")


def rounds(
    module_dir: Path, maps: Path, name: str, agents: int, steps: int, prioritize_start: bool, uneven: bool, seed: int = 0
) -> None:
    map_file = maps / name
    result, output = run_rhcr(module_dir, map_file, agents, steps, seed, 1, prioritize_start, uneven)
    calls = [ROUND.match(line) for line in output.splitlines()]
    calls = [match for match in calls if match]
    expanded = [int(m.group(3)) for m in calls]
    generated = [int(m.group(4)) for m in calls]
    # A node expanded makes two children; fewer generated means children whose agent found no path.
    dropped = [2 * e + 1 - g for e, g in zip(expanded, generated)]
    failed = sum(m.group(1) != "Succeed" for m in calls)
    print(f"\n{name}, {agents} robots, {steps} steps, seed {seed}, prioritize_start={prioritize_start}, uneven={uneven}:\n")
    print(
        "| simulator | throughput | congested | rounds given up | nodes a round (min-max) | children without a path | seconds |"
    )
    print("|---|---:|---|---:|---|---:|---:|")
    print(
        f"| RHCR | {result['throughput']:.3f} | {result['congested']} | {failed} of {len(calls)} | "
        f"{min(expanded)}-{max(expanded)} expanded | {sum(dropped)} | {result['cpu_runtime']:.0f} |"
    )
    mine = run_ours(map_file, agents, steps, seed, uneven)
    planned = -(-mine.stopped_at // 5)
    print(
        f"| structgen `pbs` | {mine.throughput:.3f} | {mine.congested} | {mine.fallbacks} of {planned} | "
        f"{mine.nodes} children in all | {mine.failed_children} | {mine.seconds:.0f} |"
    )


def sweep(module_dir: Path, maps: Path, name: str, robots: list[int], steps: int, uneven: bool, output: Path) -> None:
    """RHCR's throughput at each robot count (seed 0), printed and written to ``output`` as JSON."""
    points = []
    for agents in robots:
        began = time.perf_counter()
        result, _ = run_rhcr(module_dir, maps / name, agents, steps, 0, 0, True, uneven)
        points.append({"robots": agents, "throughput": result["throughput"], "congested": bool(result["congested"])})
        print(
            f"| {agents} | {result['throughput']:.3f} | {result['congested']} | {time.perf_counter() - began:.0f} |", flush=True
        )
    output.write_text(json.dumps({"map": name, "steps": steps, "uneven": uneven, "points": points}, indent=1) + "\n")
    print(f"wrote {output}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "what", choices=("speed", "rounds", "sweep"),
        help="time both (speed), compare one run round by round (rounds), or RHCR at several robot counts (sweep)",
    )  # fmt: skip
    parser.add_argument("--original", type=Path, default=None, help="a checkout of the original (default: clone it)")
    parser.add_argument(
        "--build-dir", type=Path, default=Path(os.environ.get("TMPDIR", "/tmp")) / "structgen-rhcr",
        help="scratch folder for the clone and the build (reused; default $TMPDIR/structgen-rhcr)",
    )  # fmt: skip
    parser.add_argument("--repeats", type=int, default=3, help="speed: timed runs of each, the median reported (default 3)")
    parser.add_argument("--agents", type=int, default=1500, help="rounds: robots (default 1500)")
    parser.add_argument("--steps", type=int, default=300, help="rounds: steps (default 300)")
    parser.add_argument("--map", default=LARGE, help="rounds: a reference map under the data folder (default: the paper's "
                        "CMA-MAE a=5 layout grown to 101x102)")  # fmt: skip
    parser.add_argument("--no-prioritize-start", action="store_true", help="rounds: run RHCR with prioritize_start off")
    parser.add_argument("--uneven", action="store_true", help="rounds, sweep: left workstations five times likelier")
    parser.add_argument("--seed", type=int, default=0, help="rounds: the simulation seed of both (default 0)")
    parser.add_argument("--robots", default="500,1000,1500,2000", help="sweep: robot counts (default 500,1000,1500,2000)")
    parser.add_argument("--output", type=Path, default=Path("rhcr_sweep.json"), help="sweep: JSON file to write")
    args = parser.parse_args()
    from structgen.domains.layouts.kinds import reference_maps

    args.build_dir.mkdir(parents=True, exist_ok=True)
    checkout = checkout_of_original(args.original, args.build_dir, REPOSITORY, ("RHCR/src",))
    maps = reference_maps()
    if maps is None:
        raise SystemExit("the reference maps are not here (set STRUCTGEN_REFERENCE_MAPS to the warehouse-maps folder)")
    module_dir = build(checkout, args.build_dir)
    if args.what == "speed":
        speed(module_dir, maps, args.repeats)
    elif args.what == "rounds":
        rounds(module_dir, maps, args.map, args.agents, args.steps, not args.no_prioritize_start, args.uneven, args.seed)
    else:
        robots = [int(n) for n in args.robots.split(",")]
        sweep(module_dir, maps, args.map, robots, args.steps, args.uneven, args.output)


if __name__ == "__main__":
    main()
