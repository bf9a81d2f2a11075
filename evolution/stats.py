"""The rule a learning result is held to: ahead of its baseline by more than three standard errors over seeds.

One place for it, so that every table that says a method learns (the benchmarks, the experiments' tables, the
results index) applies the same test: the difference of the two means against the standard error of that
difference, ``hypot(se_a, se_b)``, each standard error the sample standard deviation over ``sqrt(n)``.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["LEARNS_AT", "Comparison", "compare", "decimals_for", "mean_and_standard_error"]

#: How many standard errors of the difference a method must be ahead by to be said to learn.
LEARNS_AT = 3.0


def mean_and_standard_error(values: Sequence[float]) -> tuple[float, float]:
    """The mean and its standard error; the error is NaN for fewer than two values (one seed shows no spread)."""
    if not values:
        raise ValueError("no values to average")
    mean = statistics.fmean(values)
    return mean, (statistics.stdev(values) / math.sqrt(len(values)) if len(values) > 1 else math.nan)


def decimals_for(means: Sequence[float], errors: Sequence[float] = ()) -> int:
    """Decimal places that show three significant digits of the largest mean and one of the smallest non-zero
    standard error (at least two, at most six): a coverage of 0.0106 gets four, a QD score of 429 two, a mean of
    9.75 with a standard error of 0.0045 three."""
    scale = max((abs(v) for v in means if math.isfinite(v)), default=1.0) or 1.0
    places = 2 - math.floor(math.log10(scale))
    spread = [e for e in errors if math.isfinite(e) and e > 0]
    if spread:
        places = max(places, -math.floor(math.log10(min(spread))))
    return min(6, max(2, places))


@dataclass(frozen=True)
class Comparison:
    """A method's values over seeds against its baseline's, and the verdict of the three-standard-error rule."""

    mean: float
    standard_error: float
    baseline_mean: float
    baseline_standard_error: float

    @property
    def difference(self) -> float:
        return self.mean - self.baseline_mean

    @property
    def standard_errors(self) -> float:
        """The difference in standard errors of the difference: infinite when both spreads are 0 and the means
        differ, NaN when it cannot be told (a single seed on either side)."""
        error = math.hypot(self.standard_error, self.baseline_standard_error)
        if math.isnan(error):
            return math.nan
        if error == 0:
            return 0.0 if self.difference == 0 else math.copysign(math.inf, self.difference)
        return self.difference / error

    @property
    def learns(self) -> bool:
        """Ahead by more than :data:`LEARNS_AT` standard errors (False where that cannot be told)."""
        return self.standard_errors > LEARNS_AT

    def sentence(self, method: str, baseline: str, unit: str = "", decimals: int = 2) -> str:
        """One line a table can carry: both means with their errors (``decimals`` places) and the verdict."""
        sigmas = self.standard_errors
        if math.isnan(sigmas):
            told = "no spread on one side (one seed), so learning cannot be told"
        else:
            gap = "infinitely many" if math.isinf(sigmas) else f"{sigmas:.1f}"
            if self.learns:
                verdict = "learns"
            elif sigmas < -LEARNS_AT:
                verdict = f"is not shown to learn: {baseline} is ahead of it by more than three"
            else:
                verdict = "is not shown to learn"
            told = f"{gap} standard errors of the difference: {method} {verdict} by the three-standard-error rule"
        return (
            f"{method} {self.mean:,.{decimals}f} ± {self.standard_error:,.{decimals}f}{unit} against {baseline} "
            f"{self.baseline_mean:,.{decimals}f} ± {self.baseline_standard_error:,.{decimals}f}{unit}: {told}"
        )


def compare(values: Sequence[float], baseline: Sequence[float]) -> Comparison:
    """``values`` (the method's, one per seed) against ``baseline``'s."""
    mean, error = mean_and_standard_error(values)
    baseline_mean, baseline_error = mean_and_standard_error(baseline)
    return Comparison(mean, error, baseline_mean, baseline_error)
