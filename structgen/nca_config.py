"""The NCA's settings and the size of its weight vector: everything about the local NCA that needs no torch.

:mod:`structgen.nca` (which loads torch) grows structures with these settings and re-exports everything here; this
module exists so that reading the settings (for a configuration file, for the defaults ``--help`` shows) stays cheap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from structgen.config import Limit, check_limits
from structgen.lattice import N_NEIGHBOURS
from structgen.structure import MAX_COORDINATE

__all__ = ["INIT_SCALE", "N_INPUTS", "N_OUTPUTS", "NCAConfig", "grow_command", "n_params"]

N_INPUTS = 2 * N_NEIGHBOURS
N_OUTPUTS = N_NEIGHBOURS
# Upper bounds of the settings: far above any use, low enough that nothing computed from them overflows.
MAX_HIDDEN, MAX_ITERATIONS, MAX_VERTICES = 100_000, 100_000, 2**31 - 1
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

    section: ClassVar[str] = "NCA"
    limits: ClassVar[dict[str, Limit]] = {
        "hidden": Limit(1, MAX_HIDDEN, "hidden layer size"),
        "iterations": Limit(0, MAX_ITERATIONS, "growth steps from the seed vertex"),
        "cutoff": Limit(0, 1, "an output fires above this sigmoid value", whole=False, above=True, below=True),
        "max_vertices": Limit(1, MAX_VERTICES, "stop growth before exceeding this many vertices"),
        "max_extent": Limit(1, MAX_COORDINATE, "never build further than this many cells from the seed"),
    }

    hidden: int = 60
    iterations: int = 5
    cutoff: float = 0.5
    build_down: bool = True
    max_vertices: int = 10_000
    max_extent: int = 32

    def __post_init__(self) -> None:
        check_limits(self)
        if not isinstance(self.build_down, bool):
            raise ValueError(f"NCA build_down must be true or false, got {self.build_down!r}")


def n_params(config: NCAConfig | None = None) -> int:
    """Length of the flat weight vector (4766 for the paper's 52-60-26 network)."""
    hidden = (config or NCAConfig()).hidden
    return N_INPUTS * hidden + hidden + hidden * N_OUTPUTS + N_OUTPUTS


def grow_command(weights: object, config: NCAConfig, output: str) -> str:
    """The ``structgen grow`` line that grows ``weights`` (a file's path) with ``config``'s growth settings, naming
    only those that differ from the defaults besides the growth box and steps (what teaching fits)."""
    default = NCAConfig()
    options = [f"--max-extent {config.max_extent}", f"--iterations {config.iterations}"]
    options += [f"--hidden {config.hidden}"] * (config.hidden != default.hidden)
    options += [f"--cutoff {config.cutoff:g}"] * (config.cutoff != default.cutoff)
    return f"structgen grow --weights {weights} {' '.join(options)} -o {output}"
