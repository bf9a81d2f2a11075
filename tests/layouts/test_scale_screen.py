"""The archive screen of benchmarks/scale_screen.py picks its candidates spread over the archive: the best elite by
training's objective in each block of cells, best blocks first."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

# Appended, not put first: benchmarks/ holds scripts named physics.py and grid.py that must not shadow packages.
sys.path.append(str(Path(__file__).resolve().parents[2] / "benchmarks"))
from scale_screen import BLOCK, candidates  # noqa: E402  (a script beside the benchmarks, not a package)

from evolution.runfolder import Archive  # noqa: E402


def _archive(cells, throughput, similarity) -> Archive:
    cells = np.array(cells)
    columns = {
        "index": np.arange(len(cells)),
        "cell_a": cells[:, 0],
        "cell_b": cells[:, 1],
        "a": cells[:, 0].astype(float),
        "b": cells[:, 1].astype(float),
        "throughput": np.array(throughput, dtype=float),
        "similarity": np.array(similarity, dtype=float),
    }
    return Archive(columns, ("a", "b"))


def test_one_candidate_per_block_the_best_by_training_objective():
    # Rows 0-2 share the block (0, 0); row 1 wins there by its similarity (alpha 5), not its throughput.
    archive = _archive(
        [(0, 0), (1, 2), (BLOCK - 1, 0), (BLOCK, 0), (3 * BLOCK, 5 * BLOCK)],
        throughput=[6.0, 5.0, 4.0, 3.0, 1.0],
        similarity=[0.5, 0.9, 0.1, 1.0, 0.2],
    )
    # objectives: 8.5, 9.5, 4.5, 8.0, 2.0 -> blocks' best rows 1 (9.5), 3 (8.0), 4 (2.0)
    assert candidates(archive, alpha=5.0, count=10) == [1, 3, 4]
    assert candidates(archive, alpha=5.0, count=2) == [1, 3]
    assert candidates(archive, alpha=0.0, count=1) == [0]  # throughput alone
