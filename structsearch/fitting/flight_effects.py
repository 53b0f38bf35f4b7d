"""Flight effects: per-flight nuisance parameters estimated with a candidate as fixed effects (docs/interfaces.md
section 7.5, docs/guide/flight-effects.md).

What every maneuver of one flight shares and the data reduction gets wrong by that flight's amount (the loading
sheet's centre of gravity, a thrust-model or mass error) offsets the coefficient of the whole flight. Declared per
entry of a model spec (``flight_effects = ["x_cg", "intercept"]``) or for every candidate of a fit
(``--flight-effects``), each effect adds one parameter per flight that enters the model linearly: the fit keeps its
separable shape (the engine sees extra named regressors on extra data columns, the flights' codes).

- ``intercept``: an offset of the coefficient, column ``c_f`` (flight f's code).
- ``x_cg``: an offset ``delta_f`` of the recorded centre of gravity [m]. Its effect on the model is the model's own
  sensitivity to x_cg: with one regressor g reading x_cg and coefficient theta, ``theta g(x_cg + delta_f) =
  theta g(x_cg) + (theta delta_f) dg/dx_cg`` to first order (exact where g is linear in x_cg, as
  ``x_cg/cbar*CL`` is), so the column is ``dg/dx_cg c_f`` and its coefficient ``theta delta_f``; ``delta_f`` is
  reported as that coefficient over theta (delta method). Not the rigid-body transfer ``C_N delta_f / cbar``:
  the fitted cg term is not the rigid-body one (the thesis' Cm_xcgCL is -0.96, the transfer's +1), and the
  model's own sensitivity is the one its x_cg column was fitted with.
  A pitch model about the fixed reference point (``moment_reference = "fixed"``, :mod:`structsearch.data.
  moment_transfer`) reads x_cg only through the known transfer ``Cm_transfer = (x_cg - x_ref)/cbar C_N`` (coefficient
  1, never estimated): the column is ``d(Cm_transfer)/dx_cg c_f = C_N/cbar c_f`` (exact: the transfer is linear in
  x_cg) and its coefficient is ``delta_f`` itself, in metres. The cg-referenced model cannot tell a per-flight cg
  offset from its own cg term where the cg is constant within each flight (every column is then a per-flight
  multiple of the sensitivity); about the fixed point the coefficient is known and C_N varies within every
  maneuver, so the offsets are identified by that variation.

Coding: sum to zero. With the training flights F_1..F_K (in the order first flown), flight k < K has the code
column ``1[F_k] - 1[F_K]``; the offsets sum to zero over the flights, so the model's own intercept and cg terms
keep the mean flight and F_K's offset is minus the others' sum (its standard deviation from their covariance).
A maneuver of a flight the training maneuvers do not hold (validation, a cross-validation fold) gets code 0: the
mean flight, zero offset.
"""
from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from ..data.errors import DataError, DeclarationError
from ..data.flightdata import FlightData
from ..data.moment_transfer import TRANSFER_NAME
from ..engine.regressors import declare, symbol_names
from ..data.reading import shown

EFFECTS = ("intercept", "x_cg")
CG = "x_cg"
CODE_PREFIX = "flight_code_"     # the data column of training flight k's code (k = 1 .. K - 1)
PARAM_PREFIX = "flight_effect_"  # an effect's parameter in the fit: flight_effect_<effect>_<k>
# Below this many flights the mean flight (what an unseen flight is predicted with) rests on few flights and each
# offset on a flight's few maneuvers: the fit says so.
FEW_FLIGHTS = 5
UNSEEN_NOTE = ("a maneuver of a flight the training maneuvers do not hold (a validation flight, a flight held out "
               "by a cross-validation fold) is predicted with zero offset: the mean flight")


def parse_effects(value, where: str) -> tuple[str, ...]:
    """The ``flight_effects`` of a spec entry or an option: a list of names out of :data:`EFFECTS`, each once."""
    if value is None:
        return ()
    if isinstance(value, str) or not isinstance(value, (list, tuple)):
        raise DeclarationError(f"{where}: flight_effects is a list of names out of {', '.join(EFFECTS)} "
                               f"(e.g. [\"x_cg\"]), not {shown(value)}")
    out: list[str] = []
    for name in value:
        if not isinstance(name, str) or name not in EFFECTS:
            close = difflib.get_close_matches(str(name), EFFECTS, n=1, cutoff=0.5)
            hint = f" (did you mean {shown(close[0])}?)" if close else ""
            raise DeclarationError(f"{where}: unknown flight effect {shown(name)}{hint}; known: {', '.join(EFFECTS)}")
        if name in out:
            raise DeclarationError(f"{where}: flight effect {shown(name)} is named twice")
        out.append(name)
    return tuple(out)


def cg_terms(regressors: Sequence[tuple[str, str]]) -> tuple[str, ...]:
    """The regressors (names) that read the x_cg column."""
    return tuple(name for name, text in regressors if CG in symbol_names(text))


def check_declared(effects: Sequence[str], regressors: Sequence[tuple[str, str]], where: str,
                   fixed: bool = False) -> None:
    """A spec entry's ``x_cg`` effect needs exactly one regressor reading x_cg (its sensitivity is the column), or,
    about the fixed reference point (``fixed``), none (the known transfer's sensitivity is the column)."""
    if CG in effects:
        reason = cg_reason(regressors, fixed)
        if reason:
            raise DeclarationError(f"{where}: flight effect 'x_cg': {reason}")


def cg_reason(regressors: Sequence[tuple[str, str]], fixed: bool = False) -> str | None:
    """Why the ``x_cg`` effect does not apply to a model with these regressors (None: it does); ``fixed``: the model
    takes C_m about the fixed reference point (it reads x_cg through the known transfer)."""
    terms = cg_terms(regressors)
    if fixed:
        if terms:
            return (f"about the fixed reference point the known transfer {TRANSFER_NAME} reads x_cg, and "
                    f"{', '.join(terms)} too: the offset's effect would be the transfer's sensitivity plus theirs "
                    "weighted by their coefficients, which is not linear in the parameters")
        return None
    if not terms:
        return "no regressor reads x_cg, so a cg offset does not reach the model"
    if len(terms) > 1:
        return (f"{len(terms)} regressors read x_cg ({', '.join(terms)}); the offset's effect would be the "
                "sum of their sensitivities weighted by their coefficients, which is not linear in the parameters")
    return None


def maneuver_flights(data: FlightData, where: str = "") -> tuple[str, ...]:
    """Each maneuver's flight (a maneuver whose flight is not recorded is a flight of its own, named after it)."""
    if data.flights is None:
        raise DataError("flight effects need each maneuver's flight, and the campaign records none (a `flight` "
                        "per maneuver in its manifest)", source=where or data.source, column="flight")
    return tuple(f if f is not None else f"(maneuver {n})" for f, n in zip(data.flights, data.names))


@dataclass(frozen=True)
class FlightCoding:
    """The sum-to-zero codes of the training flights (``labels``, in the order first flown; the last is the
    reference, whose offset is minus the others' sum)."""

    labels: tuple[str, ...]

    @classmethod
    def of(cls, train: FlightData) -> "FlightCoding":
        labels = tuple(dict.fromkeys(maneuver_flights(train)))
        if len(labels) < 2:
            raise DataError(f"flight effects need maneuvers of at least two flights; the training maneuvers are "
                            f"flown on {len(labels)} ({', '.join(labels)}): one flight's offset is the model's own "
                            "intercept", source=train.source, column="flight")
        return cls(labels)

    @property
    def columns(self) -> tuple[str, ...]:
        return tuple(f"{CODE_PREFIX}{k}" for k in range(1, len(self.labels)))

    def coded(self, data: FlightData) -> FlightData:
        """``data`` with the code columns (0 on the maneuvers of a flight not among the training flights)."""
        flights = maneuver_flights(data) if data.flights is not None else (None,) * data.n_segments
        index = {f: i for i, f in enumerate(self.labels)}
        per_maneuver = np.zeros((data.n_segments, len(self.columns)))
        for m, f in enumerate(flights):
            i = index.get(f)
            if i is None:
                continue
            if i == len(self.labels) - 1:
                per_maneuver[m] = -1.0
            else:
                per_maneuver[m, i] = 1.0
        lengths = np.diff(data.bounds)
        rows = np.repeat(per_maneuver, lengths, axis=0)
        return data.with_columns({**data.columns, **{c: rows[:, j] for j, c in enumerate(self.columns)}})


def parameter_name(effect: str, k: int) -> str:
    return f"{PARAM_PREFIX}{effect}_{k}"


@dataclass(frozen=True)
class EffectDesign:
    """The effects a candidate's fit estimates: the coding, the effects that apply, those that do not (with the
    reason) and, for ``x_cg``, the regressor whose sensitivity is the column (about the fixed reference point,
    ``known``: the transfer :data:`~structsearch.data.moment_transfer.TRANSFER_NAME`, whose coefficient is 1, so
    the effect's coefficients are the offsets in metres)."""

    coding: FlightCoding
    effects: tuple[str, ...]
    skipped: tuple[tuple[str, str], ...] = ()
    cg_term: str | None = None
    # effects the data cannot separate from the model's own terms -> why (their offsets are NaN)
    confounded: Mapping[str, str] = dataclasses.field(default_factory=dict)
    known: bool = False          # x_cg read through the known transfer (C_m about the fixed reference point)

    @property
    def parameters(self) -> tuple[str, ...]:
        return tuple(parameter_name(e, k) for e in self.effects for k in range(1, len(self.coding.labels)))

    def columns(self, model) -> dict[str, sp.Expr]:
        """Each effect parameter's regressor (a sympy expression of the data columns and the codes)."""
        out = {}
        for effect in self.effects:
            if effect == "intercept":
                factor = sp.Integer(1)
            else:
                factor = sp.diff(self._cg_expression(model), sp.Symbol(CG, real=True))
            for k, code in enumerate(self.coding.columns, start=1):
                out[parameter_name(effect, k)] = factor * sp.Symbol(code, real=True)
        return out

    def _cg_expression(self, model) -> sp.Expr:
        """The expression the x_cg offset acts through: the cg term's regressor, or the model's known transfer."""
        if self.known:
            if model.offset is None or model.offset.name != self.cg_term:
                raise DeclarationError(f"model {shown(model.name)}: the x_cg flight effect about the fixed reference point "
                                       f"needs the known transfer {shown(self.cg_term)} as the model's offset")
            return model.offset.expr
        return next(r for r in model.regressors if r.name == self.cg_term).expr

    def model(self, model):
        """``model`` (a :class:`~structsearch.engine.stallmodel.StallModel`) with the effect regressors."""
        symbols = [s.symbol for s in model.states]
        extra = tuple(declare(name, expr, states=symbols, free_columns=True,
                              context=f"model {shown(model.name)}, flight effect {shown(name)}")
                      for name, expr in self.columns(model).items())
        return dataclasses.replace(model, regressors=model.regressors + extra)


def design(effects: Sequence[str], regressors: Sequence[tuple[str, str]], train: FlightData,
           fixed: bool = False) -> EffectDesign:
    """The :class:`EffectDesign` of ``effects`` for a model with ``regressors`` on the training maneuvers (``fixed``:
    C_m about the fixed reference point): an ``x_cg`` effect that does not apply (asked for a whole grid by an
    option) is skipped with its reason."""
    coding = FlightCoding.of(train)
    kept, skipped, term = [], [], None
    for effect in effects:
        if effect == CG:
            reason = cg_reason(regressors, fixed)
            if reason:
                skipped.append((effect, reason))
                continue
            term = TRANSFER_NAME if fixed else cg_terms(regressors)[0]
        kept.append(effect)
    # about the fixed point the column C_N/cbar c_f varies within every flight whatever the cg does
    confounded = ({CG: cg_confounded(train, term)} if term is not None and not fixed and cg_confounded(train, term)
                  else {})
    return EffectDesign(coding, tuple(kept), tuple(skipped), term, confounded, known=fixed and term is not None)


def cg_confounded(train: FlightData, term: str) -> str | None:
    """Why a per-flight cg offset cannot be told from the cg term ``term`` (None: x_cg varies within a flight).
    With x_cg constant within every flight, ``term``'s column is a per-flight multiple of its sensitivity, which
    the offsets' columns (with the model's own column of that sensitivity) span: only within-flight variation of
    x_cg separates the two."""
    flights = np.repeat(np.array(maneuver_flights(train), object), np.diff(train.bounds))
    x = np.asarray(train[CG], float)
    scale = max(float(np.max(np.abs(x))), np.finfo(float).tiny)
    if all(np.ptp(x[flights == f]) <= 1e-9 * scale for f in dict.fromkeys(flights)):
        return (f"x_cg is constant within every training flight, so a per-flight cg offset is confounded with "
                f"{term} (and the term of its sensitivity): only within-flight variation of x_cg separates them")
    return None


def reads_cg(regressors: Sequence[tuple[str, str]]) -> bool:
    return bool(cg_terms(regressors))


def missing_effects_warning(regressors: Sequence[tuple[str, str]], coefficient: str, train: FlightData,
                            effects: Sequence[str], fixed: bool = False) -> str | None:
    """The warning of a moment model that reads x_cg (about the fixed reference point, ``fixed``: through the known
    transfer), fitted without the ``x_cg`` effect on a campaign that records flights (None when it does not
    apply)."""
    if coefficient != "Cm" or CG in effects or train.flights is None or not (fixed or reads_cg(regressors)):
        return None
    n = len(dict.fromkeys(maneuver_flights(train)))
    if fixed and not reads_cg(regressors):
        return (f"the campaign records {n} flights and the moment model about the fixed reference point reads x_cg "
                f"through the known transfer {TRANSFER_NAME} without flight effects: a per-flight error of the "
                "recorded cg is left in the residuals, shared by each flight's maneuvers, and the standard "
                "deviations of a per-maneuver covariance are then too small (declare flight_effects = [\"x_cg\"] "
                "or fit with --flight-effects x_cg)")
    return (f"the campaign records {n} flights and the moment model reads x_cg ({', '.join(cg_terms(regressors))}) "
            "without flight effects: a per-flight error of the recorded cg is then read as the cg term's signal "
            "and its standard deviation is too small (declare flight_effects = [\"x_cg\"] or fit with "
            "--flight-effects x_cg)")


# ----- the estimates, reported apart from the aerodynamic parameters ------------------------------------------
@dataclass(frozen=True)
class FlightOffsets:
    """One effect's offset per training flight, with its standard deviation (NaN with ``reason`` where the data
    cannot tell it). ``offsets`` are the coefficients of the effect's columns (``intercept``: in units of the
    coefficient; ``x_cg``: theta delta_f, in metres times the cg term's coefficient, or delta_f itself about the
    fixed reference point, where the term is the known transfer); ``x_cg`` also gives ``delta_f`` in metres
    (``cg_offsets``)."""

    effect: str
    flights: tuple[str, ...]
    offsets: tuple[float, ...]
    stderr: tuple[float, ...]
    term: str | None = None                   # x_cg: the regressor whose sensitivity is the column
    cg_offsets: tuple[float, ...] = ()        # x_cg: delta_f [m], what the recorded cg is to be corrected by
    cg_stderr: tuple[float, ...] = ()
    reason: str | None = None                 # why some offsets are NaN (not identifiable)

    def to_dict(self) -> dict:
        doc = {"effect": self.effect, "flights": list(self.flights), "offsets": list(self.offsets),
               "stderr": list(self.stderr), "term": self.term, "reason": self.reason}
        if self.effect == CG:
            doc.update(cg_offsets_m=list(self.cg_offsets), cg_stderr_m=list(self.cg_stderr))
        return doc

    @classmethod
    def from_dict(cls, d: Mapping) -> "FlightOffsets":
        nan = _floats
        return cls(d["effect"], tuple(d["flights"]), nan(d["offsets"]), nan(d["stderr"]), d.get("term"),
                   nan(d.get("cg_offsets_m", ())), nan(d.get("cg_stderr_m", ())), d.get("reason"))


def _floats(values) -> tuple[float, ...]:
    return tuple(float("nan") if v is None else float(v) for v in values)


@dataclass(frozen=True)
class FlightEffects:
    """A fit's flight effects: the offsets per effect, the effects that did not apply (with the reason), the
    warnings on their identifiability, and how unseen flights are predicted."""

    flights: tuple[str, ...]
    effects: tuple[FlightOffsets, ...]
    skipped: tuple[tuple[str, str], ...] = ()
    warnings: tuple[str, ...] = ()
    coding: str = "sum-to-zero"
    reference: str = ""                       # the flight whose offset is minus the others' sum
    unseen: str = UNSEEN_NOTE

    def to_dict(self) -> dict:
        return {"flights": list(self.flights), "coding": self.coding, "reference": self.reference,
                "effects": [e.to_dict() for e in self.effects],
                "skipped": [{"effect": e, "reason": r} for e, r in self.skipped],
                "warnings": list(self.warnings), "unseen_flights": self.unseen}

    @classmethod
    def from_dict(cls, d: Mapping) -> "FlightEffects":
        return cls(tuple(d["flights"]), tuple(FlightOffsets.from_dict(e) for e in d["effects"]),
                   tuple((s["effect"], s["reason"]) for s in d.get("skipped", ())), tuple(d.get("warnings", ())),
                   d.get("coding", "sum-to-zero"), d.get("reference", ""), d.get("unseen_flights", UNSEEN_NOTE))

    def lines(self) -> list[str]:
        """The offsets as text lines (the fit summary and fit.md)."""
        out = [f"Flight effects ({self.coding} over {len(self.flights)} flights; {self.unseen}):"]
        for e in self.effects:
            unit = "delta x_cg [m]" if e.effect == CG else "offset"
            values, sds = (e.cg_offsets, e.cg_stderr) if e.effect == CG else (e.offsets, e.stderr)
            of = ("" if not e.term else f" (sensitivity of the known transfer {e.term})" if e.term == TRANSFER_NAME
                  else f" (sensitivity of {e.term})")
            out.append(f"  {e.effect}{of}: {unit}")
            out += [f"    {f:<16} {v: .4g} +- {s:.2g}" for f, v, s in zip(e.flights, values, sds)]
            if e.reason:
                out.append(f"    not identifiable: {e.reason}")
        out += [f"  {e} not estimated: {r}" for e, r in self.skipped]
        out += [f"  warning: {w}" for w in self.warnings]
        return out


def design_warnings(d: EffectDesign, n_model_params: int, n_maneuvers: int) -> tuple[str, ...]:
    """Named warnings on how well the flights can carry the effects."""
    k = len(d.coding.labels)
    out = [f"not identifiable: {reason}" for reason in d.confounded.values()]
    if k < FEW_FLIGHTS:
        out.append(f"few flights: {k} training flights (fewer than {FEW_FLIGHTS}); each offset rests on one "
                   "flight's maneuvers and the mean flight an unseen flight is predicted with on few flights")
    total = n_model_params + len(d.parameters)
    if total >= n_maneuvers:
        out.append(f"few maneuvers for the parameters: {n_model_params} model and {len(d.parameters)} flight-"
                   f"effect parameters on {n_maneuvers} training maneuvers; a per-maneuver covariance needs more "
                   "maneuvers than parameters")
    return tuple(out)


def split_estimates(estimates, d: EffectDesign, warnings: tuple[str, ...] = ()):
    """The fit's :class:`~structsearch.engine.estimates.ParameterEstimates` less the effect parameters (their
    marginal covariance block and the full fit's reference dof), and the :class:`FlightEffects`."""
    names = estimates.names
    effect_names = set(d.parameters)
    keep = np.array([n not in effect_names for n in names])
    cov = np.asarray(estimates.covariance, float)
    offsets = tuple(_offsets(estimates, d, effect) for effect in d.effects)
    dof = estimates.reference_dof
    sub = lambda m: None if m is None else np.asarray(m)[np.ix_(keep, keep)]  # noqa: E731
    aero = dataclasses.replace(
        estimates, linear_names=tuple(n for n in estimates.linear_names if n not in effect_names),
        values=np.asarray(estimates.values)[keep], covariance=cov[np.ix_(keep, keep)],
        white_covariance=sub(estimates.white_covariance),
        effective_maneuvers=None if estimates.effective_maneuvers is None
        else np.asarray(estimates.effective_maneuvers)[keep],
        unidentifiable={k: v for k, v in estimates.unidentifiable.items() if k not in effect_names},
        units={k: v for k, v in estimates.units.items() if k not in effect_names},
        stated={**estimates.stated, "reference_dof": {n: dof[n] for n, k in zip(names, keep) if k}})
    return aero, FlightEffects(d.coding.labels, offsets, d.skipped, warnings, reference=d.coding.labels[-1])


def _offsets(estimates, d: EffectDesign, effect: str) -> FlightOffsets:
    """One effect's offsets over every training flight (the reference's is minus the others' sum)."""
    names = list(estimates.names)
    idx = [names.index(parameter_name(effect, k)) for k in range(1, len(d.coding.labels))]
    values = np.asarray(estimates.values, float)
    cov = np.asarray(estimates.covariance, float)
    # offsets = A gamma: the identity for flights 1..K-1, minus the sum for the reference
    a = np.vstack([np.eye(len(idx)), -np.ones((1, len(idx)))])
    offsets = a @ values[idx]
    block = cov[np.ix_(idx, idx)]
    sd = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", a, block, a), 0.0, None))
    reasons = [estimates.unidentifiable[n] for n in (names[i] for i in idx) if n in estimates.unidentifiable]
    reason = reasons[0] if reasons else d.confounded.get(effect)
    if reason is None and not np.all(np.isfinite(sd)):
        reason = "its covariance could not be estimated (the fit names what it cannot identify)"
    if reason:
        offsets = np.full(len(offsets), np.nan)
        sd = np.full(len(sd), np.nan)
    if effect != CG:
        return FlightOffsets(effect, d.coding.labels, tuple(map(float, offsets)), tuple(map(float, sd)), reason=reason)
    if d.known:   # the transfer's coefficient is 1: the offsets are delta_f [m] themselves
        return FlightOffsets(effect, d.coding.labels, tuple(map(float, offsets)), tuple(map(float, sd)), d.cg_term,
                             tuple(map(float, offsets)), tuple(map(float, sd)), reason)
    # delta_f = offset_f / theta, by the delta method with the covariance of (offset_f, theta)
    t = names.index(d.cg_term)
    theta = values[t]
    cols = np.zeros((len(offsets), len(names)))
    cols[:, idx] = a
    grad = cols / theta
    grad[:, t] = -offsets / theta ** 2
    cg_sd = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", grad, cov, grad), 0.0, None)) if not reason else sd
    return FlightOffsets(effect, d.coding.labels, tuple(map(float, offsets)), tuple(map(float, sd)), d.cg_term,
                         tuple(map(float, offsets / theta)), tuple(map(float, cg_sd)), reason)
