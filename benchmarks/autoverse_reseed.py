"""Are the evolved games still hard to play under child orders their evolution never saw?

    python benchmarks/autoverse_reseed.py GAMES_DIR [--budget 4000] [--search-seeds 1 2 3 4 5] [--results PREFIX]

A game's fitness is the iteration at which best-first search first finds its best return, and the search breaks
ties between children in an order drawn from a seed; an evolution keeps a game that was hard under the seeds it
was judged with, which may be luck. GAMES_DIR holds each run's best game as ``trained-sS.json`` and
``random-sS.json`` (the GA's and random search's, one per run seed S: ``docs/results/autoverse-games``), or is the
``--out`` folder of ``benchmarks/random_baseline.py`` (each run's ``best/genome.json``). Every game is searched
again at one budget under each ``--search-seeds`` child order (all in one batch); a game's score is its mean
fitness over those orders. Prints each game's score, each side's mean and standard error over run seeds, and
whether the GA's games are ahead by more than three standard errors (``evolution.stats``). ``--results PREFIX``
writes PREFIX.json and PREFIX.md.
"""

from __future__ import annotations

import argparse
import platform
import re
import statistics
import sys
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
HERE = Path(__file__).resolve().parent
sys.path = [p for p in sys.path if Path(p or ".").resolve() != HERE]

from evolution.files import parse_json, read_text, write_table  # noqa: E402
from evolution.stats import compare, mean_and_standard_error  # noqa: E402

_NAME = re.compile(r"(trained|random)-s(\d+)")


def read_games(folder: Path) -> dict[str, dict]:
    """Each run's best game by name (``trained-s0``, ``random-s0``, ...), from run folders or from kept files."""
    from structgen.domains.autoverse.game import game_from_json

    paths = {p.name: p / "best" / "genome.json" for p in folder.iterdir() if p.is_dir() and _NAME.fullmatch(p.name)}
    if not paths:
        paths = {p.stem: p for p in folder.glob("*.json") if _NAME.fullmatch(p.stem)}
    return {name: game_from_json(parse_json(read_text(path, 10 << 20, what="a game JSON file"), str(path)), str(path))
            for name, path in sorted(paths.items())}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("games", type=Path, metavar="GAMES_DIR", help="kept games, or random_baseline.py's --out")
    parser.add_argument("--budget", type=int, default=4000, help="search expansions (default 4000: the GA's final "
                        "budget in the committed runs)")  # fmt: skip
    parser.add_argument("--search-seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5],
                        help="child-order seeds to search each game under (default 1 to 5)")  # fmt: skip
    parser.add_argument("--results", type=Path, default=None, metavar="PREFIX", help="also write PREFIX.json and .md")
    args = parser.parse_args()
    if not args.games.is_dir():
        parser.error(f"{args.games}: not a folder")
    if args.budget < 1:
        parser.error(f"--budget: {args.budget}: at least 1")
    games = read_games(args.games)
    if not games:
        parser.error(f"{args.games}: no trained-sS.json or random-sS.json, and no run folders of those names")

    from structgen.domains.autoverse.search import search, search_fitness

    names = list(games)
    run_seeds = sorted({int(_NAME.fullmatch(name).group(2)) for name in names})
    if missing := [f"{tag}-s{s}" for s in run_seeds for tag in ("trained", "random") if f"{tag}-s{s}" not in games]:
        parser.error(f"{args.games}: each run seed needs both a trained and a random game; missing {', '.join(missing)}")
    batch = [games[name] for name in names for _ in args.search_seeds]
    seeds = [seed for _ in names for seed in args.search_seeds]
    results = search(batch, args.budget, seeds)
    per_seed = len(args.search_seeds)
    fitness = {name: [search_fitness(r) for r in results[k * per_seed : (k + 1) * per_seed]] for k, name in enumerate(names)}

    lines = [f"Each run's best game searched again at budget {args.budget:,} under child orders "
             f"{', '.join(map(str, args.search_seeds))}; a game's score is its mean fitness over them. "
             f"{platform.processor() or platform.machine()}, Python {platform.python_version()}.", "",
             "| best game of | " + " | ".join(f"seed {s}" for s in run_seeds) + " | mean ± s.e. |",
             "|---|" + "---:|" * (len(run_seeds) + 1)]  # fmt: skip
    sides = {}
    for tag, label in (("trained", "the GA"), ("random", "random search")):
        scores = [statistics.fmean(fitness[f"{tag}-s{s}"]) for s in run_seeds]
        mean, error = mean_and_standard_error(scores)
        sides[label] = {"scores": scores, "mean": mean, "standard_error": error,
                        "fitness": {f"seed {s}": fitness.get(f"{tag}-s{s}") for s in run_seeds}}  # fmt: skip
        cells = " | ".join(f"{s:,.0f}" for s in scores)
        lines.append(f"| {label} | {cells} | {mean:,.0f} ± {error:,.0f} |")
    ours, theirs = (side["scores"] for side in sides.values())
    compared = compare(ours, theirs)
    lines += ["", "Searched again, the best games: " + compared.sentence("the GA", "random search", decimals=0) + "."]
    text = "\n".join(lines)
    print(text)
    if args.results is not None:
        report = {"budget": args.budget, "search_seeds": args.search_seeds, "run_seeds": run_seeds, "sides": sides,
                  "standard_errors": compared.standard_errors, "learns": compared.learns}  # fmt: skip
        write_table(args.results, report, text + "\n")


if __name__ == "__main__":
    main()
