"""The static frame solve against PyBullet: verdict agreement, rank correlation of Q, and cost.

    python benchmarks/statics.py [--reference runs/statics_reference.json] [--workers 2]

The validation set has 240 structures of 4 to 60 vertices: 100 grown by random NCAs (one-step "stars", free and
under the no-building-down rule, and two-step growths) and 140 grown by NCAs evolved in the learning runs
(``benchmarks/data/evolved_structures.json``, spread evenly over sizes). Every structure is simulated with the
faithful and the fast preset (the reference; cached in ``--reference`` because the faithful runs take about
15 minutes on two cores) and predicted by ``physics.statics`` at several load factors. Prints markdown tables.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

from physics import PhysicsConfig, check_many  # noqa: E402
from physics.statics import check_statics  # noqa: E402
from structgen import NCAConfig, Structure, grow_population, random_weights  # noqa: E402

HERE = Path(__file__).resolve().parent
# The statics settings fitted against the faithful preset (on the even-numbered structures), and variants that undo
# one fitted choice at a time.
VARIANTS = {
    "calibrated (the defaults)": {},
    "uncalibrated (thin beams, no dynamic factors, no margin)": {
        "statics_beam_radius": 0.08,
        "statics_load_factor": 1.0,
        "statics_shear_factor": 1.0,
        "statics_tip_margin": 0.0,
    },
    "calibrated, but thin beams (radius 0.08 m)": {"statics_beam_radius": 0.08},
    "calibrated, but no dynamic factors": {"statics_load_factor": 1.0, "statics_shear_factor": 1.0},
    "calibrated, but one factor 1.1 for all loads": {"statics_load_factor": 1.1, "statics_shear_factor": 1.1},
    "calibrated, but no tipping margin": {"statics_tip_margin": 0.0},
}


def validation_set() -> list[tuple[str, Structure]]:
    """(origin, structure) pairs: 100 from random NCAs, 140 from evolved ones; deterministic."""
    chosen: list[tuple[str, Structure]] = []
    random_kinds = [
        ("random NCA, 1 step", NCAConfig(iterations=1), 50),
        ("random NCA, 1 step, no build down", NCAConfig(iterations=1, build_down=False), 30),
        ("random NCA, 2 steps, no build down", NCAConfig(iterations=2, build_down=False, max_vertices=60), 20),
    ]
    for seed, (origin, config, count) in enumerate(random_kinds):
        grown = grow_population(random_weights(20 * count, seed=100 + seed, config=config), config)
        chosen += [(origin, s) for s in grown if 4 <= s.n_vertices <= 60][:count]
    evolved = json.loads((HERE / "data" / "evolved_structures.json").read_text())["structures"]
    evolved.sort(key=lambda s: (len(s["vertices"]), s["source"]))
    picks = np.linspace(0, len(evolved) - 1, 140).round().astype(int)
    chosen += [("evolved NCA", Structure(evolved[i]["vertices"], evolved[i]["edges"])) for i in picks]
    return chosen


def reference(structures: list[Structure], path: Path, workers: int) -> dict[str, list[dict]]:
    """PyBullet reports (faithful and fast) of every structure, from the cache at ``path`` if it matches."""
    fingerprint = [s.n_vertices * 100000 + s.n_edges for s in structures]
    if path.exists():
        cached = json.loads(path.read_text())
        if cached.get("fingerprint") == fingerprint:
            return cached
    results: dict = {"fingerprint": fingerprint}
    for name in ("faithful", "fast"):
        started = time.perf_counter()
        reports = check_many(structures, PhysicsConfig.preset(name), workers=workers)
        print(
            f"(simulated {len(structures)} structures with the {name} preset in {time.perf_counter() - started:.0f} s)",
            file=sys.stderr,
        )
        results[name] = [
            {
                "intact": r.intact,
                "integrity": r.integrity,
                "height": r.height,
                "score": r.score,
                "cpu": r.cpu_time,
                "error": r.error,
            }
            for r in reports
        ]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results))
    return results


def compare(predicted: list, simulated: list[dict]) -> tuple[float, float, float]:
    verdict = np.mean([p.intact == s["intact"] for p, s in zip(predicted, simulated)])
    predicted_q, simulated_q = [p.score for p in predicted], [s["score"] for s in simulated]
    rho = spearmanr(predicted_q, simulated_q).statistic if np.std(simulated_q) > 0 else float("nan")
    d_integrity = np.mean([abs(p.integrity - s["integrity"]) for p, s in zip(predicted, simulated)])
    return float(verdict), float(rho), float(d_integrity)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--reference", type=Path, default=Path("runs/statics_reference.json"), help="cache of the PyBullet results"
    )
    parser.add_argument("--workers", type=int, default=2, help="processes for the simulations (default 2)")
    args = parser.parse_args()
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "?")
    print(f"machine: {cpu}, {os.cpu_count()} cores; Python {platform.python_version()}\n")

    pairs = validation_set()
    origins = np.array([o for o, _ in pairs])
    structures = [s for _, s in pairs]
    sizes = np.array([s.n_vertices for s in structures])
    ref = reference(structures, args.reference, args.workers)
    faithful, fast = ref["faithful"], ref["fast"]
    print(
        f"{len(structures)} structures, {sizes.min()} to {sizes.max()} vertices (median {np.median(sizes):.0f}); "
        f"faithful verdicts: {sum(r['intact'] for r in faithful)} intact, {sum(not r['intact'] for r in faithful)} broken.\n"
    )

    print("## Static prediction against PyBullet\n")
    print("Agreement with the faithful preset on all 240 structures, on the 120 the statics settings were fitted on")
    print("(even positions) and on the 120 held out (odd positions).\n")
    print(
        "| predictor | same verdict (all) | rho of Q (all) | same verdict (fitted half) | rho (fitted half) | same verdict (held-out half) | rho (held-out half) | mean abs dI |"
    )
    print("|---|---|---|---|---|---|---|---|")
    halves = {"all": np.ones(len(structures), dtype=bool), "fit": np.arange(len(structures)) % 2 == 0}
    halves["held"] = ~halves["fit"]

    def row(name: str, predicted: list) -> None:
        cells = []
        for mask in halves.values():
            verdict, rho, _ = compare([p for p, m in zip(predicted, mask) if m], [r for r, m in zip(faithful, mask) if m])
            cells += [f"{100 * verdict:.1f} %", f"{rho:.3f}"]
        print(f"| {name} | {' | '.join(cells)} | {compare(predicted, faithful)[2]:.3f} |")

    row("PyBullet, fast preset", [_Row(r) for r in fast])
    predictions = {}
    for name, changes in VARIANTS.items():
        config = PhysicsConfig.preset("fast", **changes)
        predictions[name] = [check_statics(s, config) for s in structures]
        row(f"statics, {name}", predictions[name])
    print()

    print("## By origin (statics, calibrated)\n")
    print("| origin | structures | faithful intact | same verdict | Spearman rho of Q |")
    print("|---|---|---|---|---|")
    default = predictions["calibrated (the defaults)"]
    for origin in dict.fromkeys(origins):
        mask = origins == origin
        sub_pred = [p for p, m in zip(default, mask) if m]
        sub_ref = [r for r, m in zip(faithful, mask) if m]
        v, r, _ = compare(sub_pred, sub_ref)
        rho = "-" if np.isnan(r) else f"{r:.3f}"
        print(f"| {origin} | {mask.sum()} | {sum(x['intact'] for x in sub_ref)} | {100 * v:.1f} % | {rho} |")
    print()

    print("## Cost per structure\n")
    print(
        "Statics: CPU time of `check_statics` in this process, median of 3 repetitions. PyBullet: the simulating process's CPU time.\n"
    )
    print("| vertices | structures | statics median ms | statics max ms | fast preset median ms | faithful preset median ms |")
    print("|---|---|---|---|---|---|")
    config = PhysicsConfig.preset("fast")
    costs = []
    for s in structures:
        times = []
        for _ in range(3):
            started = time.process_time()
            check_statics(s, config)
            times.append(time.process_time() - started)
        costs.append(statistics.median(times) * 1e3)
    costs = np.array(costs)
    for low, high in ((4, 16), (17, 30), (31, 45), (46, 60), (4, 60)):
        mask = (sizes >= low) & (sizes <= high)
        print(
            f"| {low}-{high} | {mask.sum()} | {np.median(costs[mask]):.2f} | {costs[mask].max():.2f} "
            f"| {1e3 * np.median([r['cpu'] for r, m in zip(fast, mask) if m]):.0f} | {1e3 * np.median([r['cpu'] for r, m in zip(faithful, mask) if m]):.0f} |"
        )


class _Row:
    """A cached report seen through the attributes compare() reads."""

    def __init__(self, row: dict) -> None:
        self.intact, self.integrity, self.score = row["intact"], row["integrity"], row["score"]


if __name__ == "__main__":
    main()
