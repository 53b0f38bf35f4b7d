"""The estimates of a fit's parameters and every statistic of them: one immutable object that a
:class:`~.results.FitResult` and a search's candidate result both compose, so each statistic has one
name and one formula (``params``, ``stderr``, ``p_values``, ``cov_params()``, ``conf_int()``,
``wald_test()``; ``summary()`` on the results, rendered by :mod:`.summary`).

The named statistics are derived lazily from the stored estimate and covariance. A result rebuilt from
a summary that has no covariance (a table, a test's constructed result) may *state* some of them
instead (:attr:`ParameterEstimates.stated`); a stated statistic wins over the derived one.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np
from scipy import special

from ..data.atomic import json_ready
from .statistics import covariance_kind

if TYPE_CHECKING:
    import pandas

HIGH_CORRELATION = 0.9
# Where the solver left a parameter on its bound: the trust-region solver stops short of an active bound by
# ~1e-7..1e-6 of the range (it keeps iterates strictly inside), so 1e-5 of the range catches those stops without
# touching an interior optimum. A numerical tolerance (profiles, the benchmarks' "on a bound"); the flag a fit
# reports is the practical one below.
AT_BOUND_RTOL = 1e-5
# A parameter is reported at its bound (``at_bound``) when it lies within this fraction of its box of the bound,
# or closer to it than its own standard deviation. 1e-3 of the default boxes is 2 ms of a time constant (a fifth
# of a sample at 100 Hz), 0.2 1/rad of a1 and 0.02 deg of alpha*: nothing a flight-test engineer would tell from
# the bound, while an optimizer that ran out of evaluations on its way there (a1 = 199.997 of 200) is caught. An
# estimate whose standard deviation reaches the bound is one the data do not place inside the box either.
PRACTICAL_BOUND_FRACTION = 1e-3
# The statistics a result rebuilt from a summary may state instead of deriving them.
STATABLE = ("stderr", "p_values", "at_bound", "high_correlations", "correlation", "not_identifiable",
            "reference_dof")
# The statistics a fit whose optimizer did not converge withholds (``withheld``), stated or not.
WITHHELD = frozenset({"stderr", "p_values", "high_correlations", "correlation", "not_identifiable"})


@dataclass(frozen=True)
class WaldTest:
    """The Wald test that the parameters ``names`` are all zero: statistic b^T Cov^-1 b, referred to
    F(q, dof) with dof the fewest reference degrees of freedom among them (chi2(q) when none is finite).
    A test that cannot be made has a NaN statistic and p-value and says why in ``reason``."""

    names: tuple[str, ...]
    statistic: float
    dof: int                       # q, the number of restrictions
    denominator_dof: float         # NaN for the chi2 reference
    p_value: float
    reason: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return json_ready({"names": list(self.names), "statistic": self.statistic, "dof": self.dof,
                           "denominator_dof": self.denominator_dof, "p_value": self.p_value, "reason": self.reason})


@dataclass(frozen=True, eq=False)
class ParameterEstimates:
    """Estimates of a fit's parameters (nonlinear first, then linear), their box, their covariance and
    what it rests on. ``covariance`` is the one of ``covariance_kind``; ``white_covariance`` the white one,
    kept for comparison (None when not computed). Rows and columns of a parameter that cannot be
    estimated are NaN, with the reason in ``unidentifiable`` or derived in :attr:`not_identifiable`."""

    nonlinear_names: tuple[str, ...]
    linear_names: tuple[str, ...]
    values: np.ndarray
    lower: np.ndarray                       # box of the nonlinear parameters
    upper: np.ndarray
    covariance: np.ndarray
    covariance_kind: str
    n_samples: int
    n_maneuvers: int                        # independent records the residuals were split into
    white_covariance: np.ndarray | None = None
    max_lag: int | None = None              # lags of a Toeplitz estimate ("colored")
    bandwidth: float | None = None          # HAC kernel bandwidth in samples
    # per parameter, for the per-maneuver covariances: how many maneuvers its variance rests on
    effective_maneuvers: np.ndarray | None = None
    significance: float = 0.05
    # parameters the data cannot identify at the solution -> why (their covariance rows are NaN)
    unidentifiable: Mapping[str, str] = field(default_factory=dict)
    condition_number: float = float("nan")  # of the column-scaled Jacobian at the solution
    # what the covariance accounts for beyond this fit (drag/pitch: the lift model's estimation error)
    generated_regressors: str | None = None
    # statistics given rather than derived (a result rebuilt from a summary; names in STATABLE)
    stated: Mapping[str, Any] = field(default_factory=dict)
    # each parameter's unit ("1/rad", "s", "-"; .units), where the fitted model could tell it
    units: Mapping[str, str] = field(default_factory=dict)
    # the flights a covariance that groups by flight (hac-flight) rests on; None: another kind, or none recorded
    n_flights: int | None = None
    # why no statistic of the estimates is reported ("the optimizer did not converge: ..."): a covariance taken
    # where the optimizer stopped short describes no optimum, so it is NaN (standard deviations, p-values,
    # intervals and correlations with it) and every parameter names this reason; None: a converged fit
    withheld: str | None = None

    def __post_init__(self):
        if self.withheld:
            nan = np.full((len(self.values), len(self.values)), np.nan)
            object.__setattr__(self, "covariance", nan)
            object.__setattr__(self, "white_covariance", nan.copy())

    # ----- sizes -------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return self.nonlinear_names + self.linear_names

    @property
    def n_params(self) -> int:
        return len(self.values)

    @property
    def dof(self) -> int:
        return self.n_samples - self.n_params

    def _stated(self, name: str, derive):
        if self.withheld and name in WITHHELD:   # a non-converged fit states none of them either
            return derive()
        return self.stated[name] if name in self.stated else derive()

    # ----- estimates and their statistics -----------------------------------
    @cached_property
    def params(self) -> dict[str, float]:
        return dict(zip(self.names, map(float, self.values)))

    @cached_property
    def _stderr(self) -> np.ndarray:
        if "stderr" in self.stated and not self.withheld:
            return np.array([self.stated["stderr"][n] for n in self.names], float)
        return standard_deviations(self.covariance)

    @cached_property
    def stderr(self) -> dict[str, float]:
        return dict(zip(self.names, map(float, self._stderr)))

    @cached_property
    def white_stderr(self) -> dict[str, float]:
        white = (self.white_covariance if self.white_covariance is not None
                 else np.full((self.n_params, self.n_params), np.nan))
        return dict(zip(self.names, map(float, standard_deviations(white))))

    @cached_property
    def reference_dof(self) -> dict[str, float]:
        """Degrees of freedom of each parameter's t-test and interval: its effective number of maneuvers
        minus 1 for the per-maneuver covariances (``hac-maneuver``, ``cluster``), m - p otherwise."""
        def derive():
            kind = covariance_kind(self.covariance_kind)
            # restated without effective counts: the groups the kind counts (flights for hac-flight)
            groups = self.n_flights if kind.by_flight and self.n_flights is not None else self.n_maneuvers
            effective = (self.effective_maneuvers if self.effective_maneuvers is not None
                         else np.full(self.n_params, float(groups)))
            return {n: kind.reference_dof(self.n_samples, self.n_params, float(g))
                    for n, g in zip(self.names, effective)}
        return self._stated("reference_dof", derive)

    @cached_property
    def not_identifiable(self) -> dict[str, str]:
        """Parameters whose standard deviation cannot be estimated, with the reason (never reported as 0)."""
        def derive():
            if self.withheld:
                return {name: self.withheld for name in self.names}
            out = dict(self.unidentifiable)
            kind = covariance_kind(self.covariance_kind)
            too_few = kind.not_estimable(self.n_maneuvers, self.n_params, self.n_flights)
            for name, v in zip(self.names, np.diag(self.covariance)):
                if name in out:
                    continue
                if not np.isfinite(v) and too_few:
                    out[name] = too_few
                elif not np.isfinite(v):
                    out[name] = "its variance estimate is not finite: the data cannot identify it"
                elif v <= 0:
                    out[name] = (f"its {self.covariance_kind} variance estimate is "
                                 f"{'zero' if v == 0 else 'negative'} ({v:.3g}): the data cannot identify it")
            return out
        return self._stated("not_identifiable", derive)

    @property
    def identifiable(self) -> bool:
        return not self.not_identifiable

    @cached_property
    def covariance_psd(self) -> bool:
        """Whether the estimated covariance of the identifiable parameters is positive semi-definite.

        Judged on the correlation scale (eigenvalues above -1e-10); an indefinite estimate is
        reported as such, never repaired by clipping.
        """
        finite = np.all(np.isfinite(self.covariance), axis=0)
        block = self.covariance[np.ix_(finite, finite)]
        if block.size == 0:
            return True
        d = np.sqrt(np.abs(np.diag(block)))
        d[d == 0] = 1.0
        return bool(np.linalg.eigvalsh(block / np.outer(d, d)).min() > -1e-10)

    @cached_property
    def correlation(self) -> np.ndarray:
        if "correlation" in self.stated and not self.withheld:
            return np.asarray(self.stated["correlation"], float).reshape(self.n_params, self.n_params)
        s = self._stderr
        with np.errstate(divide="ignore", invalid="ignore"):
            corr = self.covariance / np.outer(s, s)  # NaN for a parameter without a standard deviation
        np.fill_diagonal(corr, 1.0)
        return corr

    @cached_property
    def t_values(self) -> dict[str, float]:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = self.values / self._stderr
        return dict(zip(self.names, map(float, t)))

    @cached_property
    def p_values(self) -> dict[str, float]:
        """Two-sided t-test of H0: parameter = 0 with the parameter's ``reference_dof``."""
        def derive():
            t = np.array(list(self.t_values.values()))
            dof = np.array([self.reference_dof[n] for n in self.names])
            return dict(zip(self.names, map(float, 2.0 * special.stdtr(dof, -np.abs(t)))))
        return self._stated("p_values", derive)

    @cached_property
    def significant(self) -> dict[str, bool]:
        return {n: p < self.significance for n, p in self.p_values.items()}

    @cached_property
    def at_bound(self) -> dict[str, str]:
        """Nonlinear parameters at a bound: name -> "lower" or "upper", the nearer one. At it means within
        PRACTICAL_BOUND_FRACTION of the box, or closer than the parameter's own standard deviation."""
        def derive():
            flags = {}
            for name, v, lo, hi, se in zip(self.nonlinear_names, self.values, self.lower, self.upper, self._stderr):
                span = hi - lo if np.isfinite(hi - lo) else max(abs(v), 1.0)
                reach = max(PRACTICAL_BOUND_FRACTION * span, se if np.isfinite(se) else 0.0)
                below, above = v - lo, hi - v     # NaN or inf for a bound that is not finite
                side = "lower" if not above < below else "upper"
                gap = below if side == "lower" else above
                if np.isfinite(gap) and gap <= reach:
                    flags[name] = side
            return flags
        return self._stated("at_bound", derive)

    @cached_property
    def high_correlations(self) -> list[tuple[str, str, float]]:
        """Pairs with |correlation| above 0.9, strongest first."""
        def derive():
            pairs = []
            c = self.correlation
            for i in range(self.n_params):
                for j in range(i + 1, self.n_params):
                    if abs(c[i, j]) > HIGH_CORRELATION:
                        pairs.append((self.names[i], self.names[j], float(c[i, j])))
            return sorted(pairs, key=lambda x: -abs(x[2]))
        return self._stated("high_correlations", derive)

    # ----- statsmodels-like views ---------------------------------------------
    def cov_params(self) -> "pandas.DataFrame":
        """The covariance as a table labelled by parameter name (NaN where not estimable)."""
        import pandas as pd
        return pd.DataFrame(self.covariance, index=list(self.names), columns=list(self.names))

    def conf_int(self, level: float = 0.95) -> "pandas.DataFrame":
        """estimate -+ t quantile (each parameter's reference dof) x standard deviation; NaN where there is no
        standard deviation. Columns ``lower`` and ``upper``, one row per parameter."""
        import pandas as pd
        dof = np.array([self.reference_dof[n] for n in self.names], float)
        from scipy import stats  # as in wald_test: only when intervals are asked for
        half = stats.t.ppf(0.5 + level / 2, dof) * self._stderr
        return pd.DataFrame({"lower": self.values - half, "upper": self.values + half}, index=list(self.names))

    def wald_test(self, names: Sequence[str]) -> WaldTest:
        """The Wald test that the parameters ``names`` are all zero, on the kept covariance."""
        names = tuple(names)
        unknown = [n for n in names if n not in self.names]
        if unknown:
            raise ValueError(f"{unknown[0]!r} is not a parameter of this fit ({', '.join(self.names)})")
        q = len(names)

        def untestable(reason: str, statistic: float = float("nan")) -> WaldTest:
            return WaldTest(names, statistic, q, float("nan"), float("nan"), reason)
        if not names:
            return untestable("no parameter to test")
        unidentified = [n for n in names if n in self.not_identifiable]
        if unidentified:
            return untestable(f"{unidentified[0]} is not identifiable: {self.not_identifiable[unidentified[0]]}")
        idx = [self.names.index(n) for n in names]
        cov = self.covariance[np.ix_(idx, idx)]
        b = self.values[idx]
        if not np.all(np.isfinite(cov)):
            return untestable("the covariance of the tested parameters is not estimable")
        try:
            w = float(b @ np.linalg.solve(cov, b))
        except np.linalg.LinAlgError:
            return untestable("the covariance of the tested parameters is singular")
        # F(q, dof): the small-sample version of chi2(q)/q (equal to it for m - p dof), the usual reference
        # for a clustered sandwich (Cameron & Miller 2015); dof: the fewest among the tested parameters
        from scipy import stats  # imported when a test is made (0.5 s that a plain fit does not need)
        finite = [d for d in (self.reference_dof.get(n, np.nan) for n in names) if np.isfinite(d)]
        if not finite:
            return WaldTest(names, w, q, float("nan"), float(stats.chi2.sf(w, q)))
        dof = min(finite)
        return WaldTest(names, w, q, float(dof), float(stats.f.sf(w / q, q, dof)))

    def covariance_record(self) -> dict[str, Any]:
        """What produced the standard errors and p-values (``fit.json``'s ``covariance``, docs/interfaces.md 6.4):
        the kind, its bandwidth (HAC kinds) or groups (the maneuvers of the per-maneuver kinds), the lags of a
        Toeplitz estimate, and each parameter's reference degrees of freedom. A kind that groups by flight also
        says what it grouped (``grouped_by``: "flights", with ``groups`` the number of flights, or "maneuvers" when
        the campaign records none). ``accounts_for``, when present, says what the covariance counts beyond the
        fit's own residuals (a drag or pitch fit: the lift model's estimation error; a joint fit: the C_L path)."""
        kind = covariance_kind(self.covariance_kind)
        record = {"kind": self.covariance_kind, "bandwidth": self.bandwidth,
                  "groups": self.n_maneuvers if kind.per_maneuver else None, "max_lag": self.max_lag,
                  "reference_dof": dict(self.reference_dof)}
        if kind.by_flight:
            by_flight = self.n_flights is not None
            record.update(groups=self.n_flights if by_flight else self.n_maneuvers,
                          grouped_by="flights" if by_flight else "maneuvers")
        if self.generated_regressors:   # what the covariance counts beyond this fit's own residuals
            record["accounts_for"] = self.generated_regressors
        return json_ready(record)

    # ----- serialisation -----------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: every array as lists, what is not finite as null (an infinite bound or condition
        number as the string "inf"), so that :meth:`from_dict` restores the same numbers."""
        return {
            "nonlinear": list(self.nonlinear_names), "linear": list(self.linear_names),
            "values": json_ready(self.values.tolist()),
            "lower": _finite_or_inf(self.lower), "upper": _finite_or_inf(self.upper),
            "covariance": json_ready(self.covariance.tolist()),
            "white_covariance": None if self.white_covariance is None else json_ready(self.white_covariance.tolist()),
            "covariance_kind": self.covariance_kind, "n_samples": self.n_samples, "n_maneuvers": self.n_maneuvers,
            "max_lag": self.max_lag, "bandwidth": json_ready(self.bandwidth),
            "effective_maneuvers": (None if self.effective_maneuvers is None
                                    else json_ready(self.effective_maneuvers.tolist())),
            "significance": self.significance, "unidentifiable": dict(self.unidentifiable),
            "condition_number": _finite_or_inf([self.condition_number])[0],
            "generated_regressors": self.generated_regressors, "units": dict(self.units),
            **({} if self.n_flights is None else {"n_flights": self.n_flights}),
            **({} if self.withheld is None else {"withheld": self.withheld}),
            "stated": json_ready({k: (np.asarray(v).tolist() if k == "correlation" else
                                      [list(p) for p in v] if k == "high_correlations" else dict(v))
                                  for k, v in self.stated.items()}),
        }

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> "ParameterEstimates":
        def array(v):
            return None if v is None else np.array([_float(x) for x in np.ravel(np.array(v, object))], float) \
                .reshape(np.shape(v))
        stated = {}
        for k, v in (doc.get("stated") or {}).items():
            if k == "correlation":
                stated[k] = array(v)
            elif k == "high_correlations":
                stated[k] = [(a, b, _float(c)) for a, b, c in v]
            elif k in ("stderr", "p_values", "reference_dof"):
                stated[k] = {n: _float(x) for n, x in v.items()}
            else:
                stated[k] = dict(v)
        return cls(nonlinear_names=tuple(doc["nonlinear"]), linear_names=tuple(doc["linear"]),
                   values=array(doc["values"]).reshape(-1),
                   lower=np.array([_float(x) for x in doc["lower"]], float),
                   upper=np.array([_float(x) for x in doc["upper"]], float),
                   covariance=array(doc["covariance"]).reshape(len(doc["values"]), len(doc["values"])),
                   covariance_kind=doc["covariance_kind"], n_samples=int(doc["n_samples"]),
                   n_maneuvers=int(doc["n_maneuvers"]), white_covariance=(
                       None if doc.get("white_covariance") is None else
                       array(doc["white_covariance"]).reshape(len(doc["values"]), len(doc["values"]))),
                   max_lag=doc.get("max_lag"), bandwidth=None if doc.get("bandwidth") is None else float(doc["bandwidth"]),
                   effective_maneuvers=array(doc.get("effective_maneuvers")),
                   significance=float(doc["significance"]), unidentifiable=dict(doc.get("unidentifiable") or {}),
                   condition_number=_float(doc.get("condition_number")),
                   generated_regressors=doc.get("generated_regressors"), stated=stated,
                   units=dict(doc.get("units") or {}),
                   n_flights=None if doc.get("n_flights") is None else int(doc["n_flights"]),
                   withheld=doc.get("withheld"))

    def __eq__(self, other) -> bool:
        return isinstance(other, ParameterEstimates) and self.to_dict() == other.to_dict()

    __hash__ = None  # mutable arrays inside: not hashable


def standard_deviations(covariance: np.ndarray) -> np.ndarray:
    """sqrt of the diagonal; NaN where a variance is zero, negative or not finite (never clipped to 0)."""
    v = np.diag(covariance)
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(v) & (v > 0), np.sqrt(np.abs(v)), np.nan)


def _finite_or_inf(values) -> list:
    """Floats for JSON: an infinity as "inf"/"-inf" (a one-sided box is not "not estimable"), NaN as null."""
    out = []
    for v in values:
        v = float(v)
        out.append(v if math.isfinite(v) else None if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    return out


def _float(v) -> float:
    """A number of :meth:`ParameterEstimates.to_dict` back: null is NaN, "inf"/"-inf" are infinities."""
    return math.nan if v is None else float(v)
