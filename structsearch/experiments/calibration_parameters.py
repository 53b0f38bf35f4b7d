"""One parameter's calibration: its Monte Carlo spread, reported standard deviation and interval coverage, judged
against the binomial Monte Carlo error of the count covered."""
from __future__ import annotations

from dataclasses import dataclass

from scipy import stats

# A parameter's 95 % coverage fails when its count of covered campaigns lies below this quantile of the binomial
# count of n campaigns at 0.95: a shortfall its Monte Carlo error explains passes (20 of 20 always does; 15 of
# 20 passes, 14 fails, where a fixed floor of 0.85 would have failed 16 of 20 for chance alone).
BINOMIAL_QUANTILE = 0.001


@dataclass(frozen=True)
class ParameterCalibration:
    model: str
    parameter: str
    truth: float
    mean: float
    mc_sd: float                # spread of the estimates over the campaigns
    reported_sd: float          # mean reported standard deviation
    coverage68: float
    coverage95: float
    n: int                      # campaigns with a finite reported standard deviation
    centred95: float = float("nan")  # coverage of the Monte Carlo mean: the standard deviation alone

    @property
    def ratio(self) -> float:
        return self.reported_sd / self.mc_sd if self.mc_sd > 0 else float("nan")

    @property
    def bias_in_sd(self) -> float:
        return (self.mean - self.truth) / self.mc_sd if self.mc_sd > 0 else float("nan")

    @property
    def covered95(self) -> int | None:
        """The campaigns whose 95 % interval covers the truth; None when no campaign had a standard deviation
        (nothing was counted)."""
        return int(round(self.coverage95 * self.n)) if self.n else None

    @property
    def binomial_floor95(self) -> int | None:
        """The fewest covered campaigns of ``n`` that 95 % intervals reach but for a chance of
        :data:`BINOMIAL_QUANTILE`: the binomial quantile of the count (None without a campaign)."""
        return int(stats.binom.ppf(BINOMIAL_QUANTILE, self.n, 0.95)) if self.n else None

    @property
    def coverage95_consistent(self) -> bool | None:
        """Whether the count covered is within the Monte Carlo error of 95 % (not below the binomial floor); None
        for a parameter no campaign estimated (:attr:`KindCalibration.estimable` leaves it out)."""
        return None if self.covered95 is None else self.covered95 >= self.binomial_floor95
