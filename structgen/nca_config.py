"""The NCA's settings and the size of its weight vector: everything about the local NCA that needs no torch.

:mod:`structgen.nca` (which loads torch) grows structures with these settings and re-exports everything here; this
module exists so that reading the settings (for a configuration file, for the defaults ``--help`` shows) stays cheap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from structgen.lattice import N_NEIGHBOURS

__all__ = ["INIT_SCALE", "N_INPUTS", "N_OUTPUTS", "NCAConfig", "n_params"]

N_INPUTS = 2 * N_NEIGHBOURS
N_OUTPUTS = N_NEIGHBOURS
#: Range of the uniform distribution random NCAs are drawn from (the paper's mutation and initial bias range).
INIT_SCALE = 0.25


@dataclass(frozen=True)
class NCAConfig:
    """Shape of the network and rules of growth. Defaults follow the paper.

    Attributes:
        hidden: size of the hidden layer (60 in the paper).
        iterations: growth steps from the seed (5 in the paper).
        cutoff: an output fires when its sigmoid exceeds this, in (0, 1) (0.5 in the paper; 0.6 among its variants).
        build_down: whether vertices may grow below the seed's level; ``False`` is the paper's "no building down".
        max_vertices: growth stops before a step that would leave more vertices than this.
        max_extent: cells further than this from the seed along any axis are never built.
    """

    hidden: int = 60
    iterations: int = 5
    cutoff: float = 0.5
    build_down: bool = True
    max_vertices: int = 10_000
    max_extent: int = 32

    def __post_init__(self) -> None:
        def need(ok: bool, name: str, what: str) -> None:
            if not ok:
                raise ValueError(f"NCA {name} must be {what}, got {getattr(self, name)!r}")

        def is_int(value: Any) -> bool:
            return isinstance(value, int) and not isinstance(value, bool)

        need(is_int(self.hidden) and self.hidden >= 1, "hidden", "a positive integer")
        need(is_int(self.iterations) and self.iterations >= 0, "iterations", "a non-negative integer")
        need(
            isinstance(self.cutoff, (int, float)) and not isinstance(self.cutoff, bool) and 0 < self.cutoff < 1,
            "cutoff",
            "a number strictly between 0 and 1",
        )
        need(isinstance(self.build_down, bool), "build_down", "true or false")
        need(is_int(self.max_vertices) and self.max_vertices >= 1, "max_vertices", "a positive integer")
        need(is_int(self.max_extent) and self.max_extent >= 1, "max_extent", "a positive integer")


def n_params(config: NCAConfig | None = None) -> int:
    """Length of the flat weight vector (4766 for the paper's 52-60-26 network)."""
    hidden = (config or NCAConfig()).hidden
    return N_INPUTS * hidden + hidden + hidden * N_OUTPUTS + N_OUTPUTS
