"""The settings of the tall search (:mod:`.tall`), in a module of their own: the command line shows their defaults
without loading the search (the statics, the simulator, the teaching)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from physics.config import PhysicsConfig
from structgen.config import Limit, check_limits
from structgen.errors import InputError

__all__ = ["MAX_LEVELS", "TallSettings"]

#: The tallest design a search may look for (a design of more grows past what the statics and simulation can hold).
MAX_LEVELS = 50


@dataclass(frozen=True)
class TallSettings:
    """What the search explores, and the physics that judges it; the same settings give the same designs on any
    number of workers.

    Attributes:
        levels: the tallest design to look for, in vertices (a level is one lattice layer).
        beam: designs of each height kept to grow the next.
        candidates: designs of each height (and of the refinement) simulated.
        max_vertices: the largest design tried.
        refine: whether to try every change of two levels' rules of the tallest design (and of lower ones while none
            above holds in the transient).
        footprint: the side, in cells, of the square every design must fit in (odd: the top vertex stands over its
            centre; reach beyond it is dropped, as an NCA's growth box drops it); 0 for no limit.
        physics: the loads and the break force they are held to (the faithful preset unless set otherwise; its size
            caps are raised for each design as far as the design needs).
    """

    section: ClassVar[str] = "search"
    limits: ClassVar[dict[str, Limit]] = {
        "levels": Limit(2, MAX_LEVELS, "tallest design to look for, in vertices (search.levels)"),
        "beam": Limit(1, 10_000, "designs of each height kept to grow the next (search.beam)"),
        "candidates": Limit(1, 10_000, "designs of each height simulated, and of the refinement (search.candidates)"),
        "max_vertices": Limit(2, 100_000, "largest design tried (search.max_vertices)"),
        "footprint": Limit(0, 1_001, "side of the square footprint designs must fit in, in cells; 0 for none (search.footprint)"),
    }

    levels: int = 8
    beam: int = 30
    candidates: int = 12
    max_vertices: int = 700
    refine: bool = True
    footprint: int = 0
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)

    @property
    def extent(self) -> int | None:
        """How far from the axis a design may reach, in cells (None: no limit)."""
        return (self.footprint - 1) // 2 if self.footprint else None

    def __post_init__(self) -> None:
        try:
            check_limits(self)
        except ValueError as err:
            raise InputError(str(err)) from None
        if self.footprint % 2 == 0 and self.footprint != 0:
            raise InputError(f"footprint must be odd (the top vertex stands over its centre) or 0 for none, got {self.footprint}")
        if not isinstance(self.refine, bool):
            raise InputError(f"refine must be true or false, got {self.refine!r}")
        if not isinstance(self.physics, PhysicsConfig):
            raise InputError(f"physics must be a PhysicsConfig, got {type(self.physics).__name__}")
