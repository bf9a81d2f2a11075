"""The static analysis against the faithful preset on two thousand structures of every origin, and every kind of
disagreement between them.

    python benchmarks/statics_agreement.py [--cache runs/statics_agreement.jsonl] [--workers 2] [--hours H]

What users must trust before using ``--statics`` (milliseconds) in place of PyBullet's 30 s: its stand/fall verdict.
The set (deterministic, built from the code and the weights in ``docs/``):

- random NCAs: one growth step (free, and under the no-building-down rule), two steps under it, three steps;
  random lattice growths (``samples.random_growth``);
- evolved NCAs: the 239 structures of ``benchmarks/data/evolved_structures.json``, and the evolved tall NCAs of
  ``docs/`` with their weights perturbed (structures near the edge of standing, where evolution leaves them);
- taught NCAs: the taught towers at every growth step, and their weights perturbed;
- designed: random one-rule-per-level designs (:func:`structgen.domains.structures.samples.by_level_rules`, the
  family the tall search draws from);
- large: the taught towers grown whole, the six-level rule design, the large flat NCA grown for more steps.

Each structure is judged by the static analysis and simulated with the faithful preset (30 s, 1/240 s steps; the
joint cap raised for the large ones). The simulations take about an hour and a half on two cores, so every result
is appended to ``--cache`` as it comes (one JSON line per structure, keyed by its index and shape): run it again to
go on, ``--hours`` to stop early. The order is shuffled (large ones last), so a partial run is a fair sample.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import sys
import time
from collections import Counter
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from physics import PhysicsConfig  # noqa: E402
from physics.parallel import CheckPool  # noqa: E402
from structgen import NCAConfig, Structure, grow_population, random_weights  # noqa: E402
from structgen.domains.structures.samples import LEVEL_RULES, by_level_rules, random_growth, six_level_rule_design  # noqa: E402
from structgen.domains.structures.stress import member_load_shares  # noqa: E402
from structgen.nca import load_weights  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
# Small enough that the faithful 30 s costs seconds; the large ones are their own kind.
SMALL = 80
# The NCAs in docs/ and the settings they grow with (as their grow commands in docs/structures.md give them).
EVOLVED_NCAS = {
    "tall_five_levels_nca.npy": NCAConfig(iterations=10, cutoff=0.6, build_down=False, max_vertices=SMALL),
    "tall_elite_start.npy": NCAConfig(iterations=10, cutoff=0.6, build_down=False, max_vertices=SMALL),
    "tall_six_level_near_miss.npy": NCAConfig(iterations=10, cutoff=0.6, build_down=False, max_vertices=SMALL),
    "tall_six_level_refined.npy": NCAConfig(iterations=10, cutoff=0.6, build_down=False, max_vertices=SMALL),
}
TAUGHT = {"tall_grown_7.npy": (6, 6), "tall_grown_8.npy": (7, 7)}  # (iterations, max extent)


def _fits(structure: Structure, low: int = 4, high: int = SMALL) -> bool:
    return low <= structure.n_vertices <= high


def _random_ncas(count: int, seed: int, config: NCAConfig, high: int = 60) -> list[Structure]:
    grown = grow_population(random_weights(8 * count, seed=seed, config=config), config)
    return [s for s in grown if _fits(s, high=high)][:count]


def _perturbed(weights: np.ndarray, count: int, seed: int, config: NCAConfig) -> list[Structure]:
    """Structures of ``weights`` with noise of several sizes added: near misses of a working NCA."""
    rng = np.random.default_rng(seed)
    scales = rng.choice([0.01, 0.03, 0.1, 0.3], size=16 * count)
    noisy = weights[None] + rng.normal(size=(16 * count, weights.size)) * scales[:, None] * np.abs(weights).mean()
    grown = grow_population(noisy, config)
    unique: dict[bytes, Structure] = {}
    for structure in grown:
        if _fits(structure):
            unique.setdefault(_shape(structure), structure)
    return list(unique.values())[:count]


def _designs(count: int, seed: int) -> list[Structure]:
    rng = np.random.default_rng(seed)
    unique: dict[bytes, Structure] = {}
    while len(unique) < count:
        rules = tuple(rng.choice(LEVEL_RULES, size=int(rng.integers(1, 5))))
        design = by_level_rules(rules, int(rng.integers(0, 3)))
        if design is not None and _fits(design):
            unique.setdefault(_shape(design), design)
    return list(unique.values())


def _shape(structure: Structure) -> bytes:
    return hashlib.sha1(structure.vertices.tobytes() + structure.edges.tobytes()).digest()


def validation_set() -> list[tuple[str, Structure]]:
    """(kind, structure) pairs, deterministic: 2,000 and a few, shuffled with the large ones last."""
    kinds: list[tuple[str, list[Structure]]] = [
        ("random NCA, 1 step", _random_ncas(300, 201, NCAConfig(iterations=1))),
        ("random NCA, 1 step, no build down", _random_ncas(250, 202, NCAConfig(iterations=1, build_down=False))),
        ("random NCA, 2 steps, no build down", _random_ncas(250, 203, NCAConfig(iterations=2, build_down=False, max_vertices=60))),
        ("random NCA, 3 steps", _random_ncas(150, 204, NCAConfig(iterations=3, max_vertices=SMALL), high=SMALL)),
        ("random lattice growth", [random_growth(int(n), seed) for seed, n in enumerate(np.linspace(8, 60, 200).round())]),
    ]  # fmt: skip
    evolved = json.loads((ROOT / "benchmarks" / "data" / "evolved_structures.json").read_text())["structures"]
    kinds.append(("evolved NCA", [Structure(s["vertices"], s["edges"]) for s in evolved]))
    near: list[Structure] = []
    for n, (name, config) in enumerate(EVOLVED_NCAS.items()):
        near += _perturbed(load_weights(DOCS / name), 63, 300 + n, config)
    kinds.append(("evolved NCA, perturbed", near))
    taught, whole = [], []
    for n, (name, (iterations, extent)) in enumerate(TAUGHT.items()):
        weights = load_weights(DOCS / name)
        for steps in range(1, iterations + 1):
            (grown,) = grow_population(weights[None], NCAConfig(iterations=steps, max_extent=extent))
            (taught if _fits(grown) else whole).append(grown)
        taught += _perturbed(weights, 100, 400 + n, NCAConfig(iterations=iterations, max_extent=extent, max_vertices=SMALL))
    kinds.append(("taught NCA", taught))
    kinds.append(("designed (one rule per level)", _designs(250, 500)))
    flat = load_weights(DOCS / "large_flat_nca.npy")
    large = [
        g for steps in (3, 4) for g in grow_population(flat[None], NCAConfig(iterations=steps, cutoff=0.6, build_down=False))
    ]
    kinds.append(("large (over 80 vertices)", [s for s in whole + [six_level_rule_design()] + large if s.n_vertices > SMALL][:8]))
    rng = np.random.default_rng(0)
    small = [(kind, s) for kind, group in kinds if not kind.startswith("large") for s in group]
    order = rng.permutation(len(small))
    return [small[i] for i in order] + [(kinds[-1][0], s) for s in kinds[-1][1]]


def _statics(structure: Structure, config: PhysicsConfig) -> dict:
    started = time.process_time()
    report, shares = member_load_shares(structure, config)
    fell = sum(joint.fell for joint in report.broken_joints)
    finite = shares[np.isfinite(shares)]
    return {
        "stands": report.stands,
        "integrity": report.integrity,
        "peak_share": float(finite.max()) if len(finite) else None,
        "no_answer": bool(np.isnan(shares).any()),
        "overloaded": len(report.broken_joints) - fell,
        "fell": fell,
        "ms": 1e3 * (time.process_time() - started),
    }


def _simulate(pending: list[tuple[int, str, Structure]], cache: Path, workers: int, deadline: float) -> None:
    config = PhysicsConfig(max_joints=10**5)
    chunk = 2 * workers
    with CheckPool(workers) as pool, cache.open("a") as out:
        for start in range(0, len(pending), chunk):
            if time.monotonic() > deadline:
                print(f"(stopped at the time limit: {len(pending) - start} structures left)", file=sys.stderr)
                return
            part = pending[start : start + chunk]
            reports = pool.check([s for _, _, s in part], config)
            for (index, kind, structure), report in zip(part, reports):
                line = {
                    "index": index, "kind": kind, "shape": _shape(structure).hex(), "vertices": structure.n_vertices,
                    "edges": structure.n_edges, "faithful": {"stands": report.stands, "integrity": report.integrity,
                    "broken": len(report.broken_joints), "error": report.error, "cpu": report.cpu_time},
                    "statics": _statics(structure, PhysicsConfig()),
                }  # fmt: skip
                out.write(json.dumps(line) + "\n")
            out.flush()
            done = start + len(part)
            print(f"  {done}/{len(pending)} simulated", file=sys.stderr, end="\r")


def _disagreement(row: dict) -> str | None:
    faithful, statics = row["faithful"], row["statics"]
    if faithful["stands"] == statics["stands"]:
        return None
    peak = statics["peak_share"]
    if statics["stands"]:
        near = peak is not None and peak >= 0.9
        return f"statics stands, PyBullet breaks ({'peak share 0.9 or more' if near else 'peak share under 0.9'})"
    if statics["overloaded"]:
        near = peak is not None and peak <= 1.1
        return f"statics breaks (overload{', peak share 1.1 or less' if near else ', peak share over 1.1'}), PyBullet stands"
    return "statics breaks (a piece falls or tips: no static answer), PyBullet stands"


def _tables(rows: list[dict]) -> str:
    lines = ["| origin | structures | vertices | faithful stands | statics stands | same verdict | mean abs dI | faithful s (median) | statics ms (median) |",
             "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    groups = {kind: [r for r in rows if r["kind"] == kind] for kind in dict.fromkeys(r["kind"] for r in rows)}
    for kind, group in [*groups.items(), ("all", rows)]:
        same = [r["faithful"]["stands"] == r["statics"]["stands"] for r in group]
        sizes = [r["vertices"] for r in group]
        d_integrity = np.mean([abs(r["faithful"]["integrity"] - r["statics"]["integrity"]) for r in group])
        lines.append(
            f"| {kind} | {len(group)} | {min(sizes)}-{max(sizes)} | {sum(r['faithful']['stands'] for r in group)} "
            f"| {sum(r['statics']['stands'] for r in group)} | {100 * np.mean(same):.1f} % | {d_integrity:.3f} "
            f"| {np.median([r['faithful']['cpu'] for r in group]):.1f} | {np.median([r['statics']['ms'] for r in group]):.1f} |"
        )
    kinds = Counter(d for d in map(_disagreement, rows) if d)
    lines += ["", "| disagreement | structures | share of all | of which origins |", "|---|---|---|---|"]
    for kind, count in kinds.most_common():
        origins = Counter(r["kind"] for r in rows if _disagreement(r) == kind)
        lines.append(f"| {kind} | {count} | {100 * count / len(rows):.1f} % | "
                     + ", ".join(f"{o} {n}" for o, n in origins.most_common()) + " |")  # fmt: skip
    errors = [r for r in rows if r["faithful"]["error"]]
    if errors:
        lines.append(f"\n{len(errors)} simulations failed: " + "; ".join(sorted({r["faithful"]["error"] for r in errors})))
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--cache",
        type=Path,
        default=Path("runs/statics_agreement.jsonl"),
        help="results so far, one JSON line per structure (appended; run again to go on)",
    )
    parser.add_argument("--workers", type=int, default=2, help="processes for the simulations (default 2)")
    parser.add_argument("--hours", type=float, default=float("inf"), help="stop simulating after this long")
    parser.add_argument("--table-only", action="store_true", help="simulate nothing: the tables of the cache as it is")
    args = parser.parse_args()  # fmt: skip
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "?")
    print(f"machine: {cpu}, {os.cpu_count()} cores; Python {platform.python_version()}\n")
    pairs = validation_set()
    args.cache.parent.mkdir(parents=True, exist_ok=True)
    done = {}
    if args.cache.exists():
        for text in args.cache.read_text().splitlines():
            row = json.loads(text)
            done[(row["index"], row["shape"])] = row
    pending = [(i, kind, s) for i, (kind, s) in enumerate(pairs) if (i, _shape(s).hex()) not in done]
    if pending and not args.table_only:
        print(f"(simulating {len(pending)} of {len(pairs)} structures with the faithful preset)", file=sys.stderr)
        _simulate(pending, args.cache, args.workers, time.monotonic() + 3600 * args.hours)
        done = {}
        for text in args.cache.read_text().splitlines():
            row = json.loads(text)
            done[(row["index"], row["shape"])] = row
    rows = [done[key] for key in ((i, _shape(s).hex()) for i, (_, s) in enumerate(pairs)) if key in done]
    print(f"{len(rows)} of {len(pairs)} structures judged by both (faithful preset and static analysis)\n")
    if rows:
        print(_tables(rows))


if __name__ == "__main__":
    main()
