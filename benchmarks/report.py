"""Run reports' size and time: `structgen report` on run folders, one row each (size in MB, seconds to write, elites
given a view), and optionally a screenshot of the first in headless Chromium (the README's picture).

    python benchmarks/report.py RUN_DIR [RUN_DIR ...] [--elites 1000] [--screenshot docs/report.png]

The issue's goals: a 200-generation main-job run's report at most 10 MB, written in at most 10 s; an archive of
1,000 structure elites at most 50 MB.
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def screenshot(page: Path, output: Path) -> None:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=shutil.which("chromium"), args=["--no-sandbox", "--use-gl=swiftshader"])
        try:
            view = browser.new_page(viewport={"width": 1200, "height": 900}, device_scale_factor=1)
            view.goto(page.as_uri())
            view.wait_for_selector("#elite-view .gl-container canvas", timeout=60_000)
            view.wait_for_timeout(1500)
            view.screenshot(path=str(output), full_page=True)
        finally:
            browser.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run folders")
    parser.add_argument("--elites", type=int, default=1000, help="archive elites given a view (default 1000)")
    parser.add_argument("--screenshot", type=Path, help="PNG of the first run's report in headless Chromium")
    args = parser.parse_args()
    from structgen.runs.report import run_page, write_page

    print("| run | domain | generations | elites in archive | elites drawn | size MB | seconds |")
    print("|---|---|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as scratch:
        for number, run in enumerate(args.runs):
            started = time.perf_counter()
            page = run_page(run, elites=args.elites)
            path = write_page(page, Path(scratch) / f"{number}.html")
            seconds = time.perf_counter() - started
            archive = run / "archive.csv"
            elites = len(archive.read_text().splitlines()) - 1 if archive.is_file() else 0
            drawn = len(re.findall(r'"name": ?"(?:best|cell \d+)"', page))
            domain = re.search(r"<title>[^:]*: ([^,]+),", page).group(1)
            generations = len((run / "metrics.jsonl").read_text().splitlines())
            print(
                f"| {run.name} | {domain} | {generations} | {elites:,} | {drawn:,} | {path.stat().st_size / 1e6:.1f} | "
                f"{seconds:.1f} |"
            )
            if number == 0 and args.screenshot:
                screenshot(path, args.screenshot)


if __name__ == "__main__":
    main()
