"""The README's Python example of a custom problem runs as written."""

from __future__ import annotations

import os
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_custom_problem_example_runs(tmp_path, monkeypatch, capsys):
    example = README.read_text().split("**From Python.**")[1].split("```python")[1].split("```")[0]
    monkeypatch.chdir(tmp_path)
    exec(compile(example, "README.md", "exec"), {"__name__": "readme_example"})
    genome, objective = capsys.readouterr().out.split()
    assert float(objective) > 1 and set(genome) <= set("abcdefghaeiouxyz")
    assert (tmp_path / "runs" / "words" / "best" / "genome.json").exists()
    assert os.listdir(tmp_path / "runs" / "words")
