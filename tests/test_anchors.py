"""The anchor scripts (benchmarks/anchors/) that time the papers' own code beside ours: they say clearly what they
need when the original is not where they were told, and never reach for the network when given a path."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ANCHORS = Path(__file__).resolve().parents[1] / "benchmarks" / "anchors"


SCRIPTS = ["growth.py", "fortress.py", "autoverse.py", "rhcr.py"]
# What each script needs besides --original to get as far as looking at the checkout.
EXTRA = {"autoverse.py": ["--python", sys.executable], "rhcr.py": ["speed"]}


@pytest.mark.parametrize("script", SCRIPTS)
def test_an_anchor_refuses_a_folder_that_is_not_the_original(script, tmp_path):
    extra = EXTRA.get(script, [])
    if script == "rhcr.py":
        extra = [*extra, "--build-dir", str(tmp_path / "build")]
    done = subprocess.run(
        [sys.executable, str(ANCHORS / script), "--original", str(tmp_path), "--repeats", "1", *extra],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode != 0
    assert str(tmp_path) in done.stderr and "not a checkout of https://github.com/" in done.stderr


@pytest.mark.parametrize("script", SCRIPTS)
def test_an_anchor_explains_its_options(script):
    done = subprocess.run([sys.executable, str(ANCHORS / script), "--help"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "--original" in done.stdout and "median" in done.stdout
