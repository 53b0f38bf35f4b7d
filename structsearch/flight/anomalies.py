"""Aerodynamics outside the model library, and how much of a campaign's coefficients an effect explains.

An :class:`Anomaly` is an effect that no candidate of the grids (and no effect of the diagnosis'
library) can express: ``build_campaign(anomaly=NAME)`` flies the Citation II with it in the truth
(or, for ``vane_lag``, in the measurement chain), so that a diagnosis can be tested on a gap it
cannot close. :func:`truth_difference` computes from the truth itself, sample by sample, the part
of a coefficient that an effect explains: the honest reference of the diagnosis benchmarks.

The sizes below were chosen to make each anomaly clearly visible: the final model of the anomaly's
coefficient (CL-VI or Cm-XXXIIIr), refitted on a campaign with it, misses the validation maneuvers by
some tens of per cent more than on the default campaign of the same seed (how much depends on the seed:
a refit absorbs what the few validation maneuvers do not tell apart). Several are larger than the
physical effect they stand for would be on a Citation II. `structsearch diagnose --benchmark` diagnoses
each one (``results/withheld_benchmark.md``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..data.coefficients import LONGITUDINAL
from ..data.errors import DeclarationError
from ..data.prefilter import derivative
from ..engine.separation import first_order_lag, is_lagged
from .aero import AeroModel, StateSpec, truth_model
from .reference import FINAL_LIFT

# Reference airspeed [m/s] and altitude [m] of the anomalies: where they leave the final model unchanged.
V_REF = 90.0
H_REF = 4500.0
# Which coefficient each withholdable effect of the final model belongs to (the one its withheld-effect
# baseline lacks it in; diagnosis/withheld.py WITHHELD says the same for the effects it benchmarks).
EFFECT_COEFFICIENT = {
    "unsteady_lag": "CL",
    "separation_delay": "CL",
    "second_separation_state": "CL",
    "pitch_rate": "CL",
    "elevator": "CL",
    "elevator_effectiveness_loss": "Cm",
    "thrust": "CD",
    "induced_drag": "CD",
    "separation_drag": "CD",
    "cp_shift": "Cm",
}


@dataclass(frozen=True)
class Anomaly:
    """An out-of-library effect: what it is, the coefficient it mainly affects and the signal its gap follows.

    How it acts (all optional): ``factors`` multiply the terms of named truth parameters by an
    expression of the data columns; ``stall_shift`` moves a state's alpha* by a rate [rad per 1000 m]
    with the altitude above ``H_REF``; ``reattachment`` gives states whose separation delay (the
    given one [s], in place of their tau2) acts only while the flow reattaches (alpha_dot < 0) and not
    at all while it separates; ``vane_lag_s`` lags the alpha vane's reading (measurement chain); ``static_forms``
    gives states another static separation curve (state symbol, form of :mod:`structsearch.engine.static_forms`,
    its parameters' values by base name) in place of their tanh.
    """

    name: str
    description: str
    coefficient: str   # "CL", "CD" or "Cm"
    signal: str        # the campaign column the gap follows
    factors: tuple[tuple[str, str], ...] = ()
    stall_shift: tuple[tuple[str, float], ...] = ()
    reattachment: tuple[tuple[str, float], ...] = ()
    vane_lag_s: float = 0.0
    static_forms: tuple[tuple[str, str, tuple[tuple[str, float], ...]], ...] = ()

    @property
    def flies(self) -> bool:
        """Whether the anomaly changes the truth aerodynamics (else only the measurement chain)."""
        return bool(self.factors or self.stall_shift or self.reattachment or self.static_forms)

    @property
    def states(self) -> tuple[str, ...]:
        """The separation states it acts on (an :class:`~.aero.AeroModel` checks it has them)."""
        return tuple(dict.fromkeys([s for s, _ in self.stall_shift + self.reattachment]
                                   + [s for s, _, _ in self.static_forms]))

    @property
    def rate_states(self) -> tuple[str, ...]:
        """The states whose target it makes depend on alpha_dot (a steady one then needs iterations)."""
        return tuple(s for s, _ in self.reattachment)

    def separation_target(self, spec: StateSpec, alpha, alpha_dot, h) -> np.ndarray:
        """The value state ``spec`` relaxes to: X0(alpha - tau2 alpha_dot) as changed by the anomaly."""
        tau2 = spec.tau2 if spec.kind != "S" else 0.0
        for symbol, form, values in self.static_forms:
            if symbol == spec.symbol:
                spec = dataclasses.replace(spec, form=form, shape=values)
        reattach = dict(self.reattachment)
        shift = dict(self.stall_shift)
        if spec.symbol in reattach:
            delay = reattach[spec.symbol] * np.minimum(alpha_dot, 0.0)
        else:
            delay = tau2 * alpha_dot
        a_star = None
        if spec.symbol in shift:
            if h is None:
                raise DeclarationError(f"anomaly {self.name!r}: the separation state {spec.symbol} depends on the "
                                       "altitude; no h given")
            a_star = spec.a_star + shift[spec.symbol] * (np.asarray(h, float) - H_REF) / 1000.0
        return spec.static(alpha - delay, a_star)


# Sizes (each chosen so that the anomaly is clearly visible, see the module docstring; most are larger
# than the physical effect they stand for would be on a Citation II):
REATTACHMENT_DELAY_S = {"X_ss": 2 * FINAL_LIFT["tau2_ss"], "X_w": 1.0}  # [s] while alpha falls; 0 while it rises
VANE_LAG_S = 0.4                 # [s] first-order lag of the alpha vane
COMPRESSIBILITY_GAIN = 1.25      # K_L terms times 1 + gain ((V/V_REF)^2 - 1)
STALL_SHIFT = {"X_w": -0.025, "X_ss": -0.0125}  # [rad per 1000 m] of alpha* above H_REF
ELEVATOR_LOSS_GAIN = 0.8         # C_m,de times 1 - gain ((V/V_REF)^2 - 1)
# The stall strips' static curve in two steps: from 1 to a plateau at the first break, from it to 0 at the second
# (two_break; the final model's alpha*_ss = 0.196 rad lies between the two breaks), both sharp, the plateau
# 0.16 rad wide; and the strips' lift share (C_L,KL_ss) times TWO_BREAK_LIFT. With the final model's share the
# steps are within noise of a tanh refitted (CL-VI's validation MSE equals the two_break truth's at scale 0.2-0.25:
# a wide tanh of a low alpha* and a larger C_L,KL_ss follows them); with 2.5 times it, at scale 0.25 (seed 0), the
# two_break structure's validation MSE (0.0043) is 14-37 % below CL-VI's (0.0050-0.0069, by the optimum its fit
# reaches from its starts).
TWO_BREAK_SS = (("k1", 150.0), ("a_k1", 0.12), ("k2", 150.0), ("da_k2", 0.16), ("x_mid", 0.5))
TWO_BREAK_LIFT = 2.5

_SPEED = f"((V/{V_REF})**2 - 1)"

ANOMALIES = {a.name: a for a in (
    Anomaly("reattachment_delay",
            "Separation is delayed only while the flow reattaches: the stall strips' delay is 0 while alpha "
            f"rises and 2 tau2_ss ({REATTACHMENT_DELAY_S['X_ss']:.3f} s) while it falls, the wing's 0 and "
            f"{REATTACHMENT_DELAY_S['X_w']:g} s, a hysteresis no S/Q/U separation state expresses.",
            "CL", "alpha_dot", reattachment=tuple(REATTACHMENT_DELAY_S.items())),
    Anomaly("vane_lag",
            f"The alpha vane reads through a first-order lag of {VANE_LAG_S:g} s before the pre-filter, so the "
            "recorded alpha and alpha_dot lag the aircraft's (every coefficient's regressors; seen most in C_m).",
            "Cm", "alpha_dot", vane_lag_s=VANE_LAG_S),
    Anomaly("compressibility",
            f"The lift-curve slope terms K_L(X_ss) and K_L(X_w) grow with airspeed: times 1 + "
            f"{COMPRESSIBILITY_GAIN:g} ((V/{V_REF:g})^2 - 1).",
            "CL", "V", factors=tuple((p, f"1 + {COMPRESSIBILITY_GAIN!r}*{_SPEED}") for p in ("CL_KL_ss", "CL_KL_w"))),
    Anomaly("reynolds_stall",
            f"The wing stalls earlier the higher it flies (the Reynolds number falls): alpha*_w falls by "
            f"{-STALL_SHIFT['X_w']:g} rad and alpha*_ss by {-STALL_SHIFT['X_ss']:g} rad per 1000 m above "
            f"{H_REF:g} m.",
            "CL", "h", stall_shift=tuple(STALL_SHIFT.items())),
    Anomaly("tail_aeroelastic",
            f"The elevator loses effectiveness as the tail twists under load: C_m,de times 1 - "
            f"{ELEVATOR_LOSS_GAIN:g} ((V/{V_REF:g})^2 - 1).",
            "Cm", "V", factors=(("Cm_de", f"1 - {ELEVATOR_LOSS_GAIN!r}*{_SPEED}"),)),
    Anomaly("two_break_stall",
            "The stall strips separate in two steps: their static curve X0_ss falls from 1 to a plateau of "
            f"{dict(TWO_BREAK_SS)['x_mid']:g} at {dict(TWO_BREAK_SS)['a_k1']:g} rad and from it to 0 "
            f"{dict(TWO_BREAK_SS)['da_k2']:g} rad later (the two_break form, both breaks sharp), which no tanh "
            f"follows; the strips carry {TWO_BREAK_LIFT:g} times the final model's lift (C_L,KL_ss), so that the "
            "steps show in C_L.",
            "CL", "alpha", factors=(("CL_KL_ss", repr(TWO_BREAK_LIFT)),),
            static_forms=(("X_ss", "two_break", TWO_BREAK_SS),)),
)}


def anomaly_named(name: str) -> Anomaly:
    try:
        return ANOMALIES[name]
    except KeyError:
        raise DeclarationError(f"no anomaly {name!r}: the simulator flies {', '.join(ANOMALIES)}") from None


def flown_states(model: AeroModel, data, alpha: np.ndarray | None = None,
                 alpha_dot: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """``model``'s separation states over ``data`` (FlightData): targets from the measured alpha,
    alpha_dot (or the ones given) and h, the unsteady states lagged per maneuver from equilibrium at
    its first sample (:func:`~structsearch.engine.separation.first_order_lag`, as a fit evaluates them)."""
    alpha = data["alpha"] if alpha is None else alpha
    alpha_dot = data["alpha_dot"] if alpha_dot is None else alpha_dot
    h = data["h"] if "h" in data else None
    targets = model.separation_targets(alpha, alpha_dot, h)
    out = {}
    for s in model.states:
        x = targets[s.symbol]
        if is_lagged(s.kind):
            x = first_order_lag(data["t"], x, np.zeros((len(x), 1)), s.tau1, data.bounds)[0]
        out[s.symbol] = x
    return out


def flown_terms(model: AeroModel, data, coefficient: str, alpha: np.ndarray | None = None,
                alpha_dot: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The terms of ``model``'s ``coefficient`` on the flown (measured) states of ``data``; C_D and C_m
    take C_L from ``model`` itself, not the measured one."""
    values = {name: data[name] for name in data.columns}
    values.update(data.constants)
    if alpha is not None:
        values["alpha"], values["alpha_dot"] = alpha, alpha_dot
    values.update(flown_states(model, data, alpha, alpha_dot))
    if coefficient != "CL":
        values["CL"] = model.coefficient("CL", values)
    return model.terms(coefficient, values)


def _difference(actual: dict[str, np.ndarray], reference: dict[str, np.ndarray], n: int) -> np.ndarray:
    """Sum of the term-by-term differences: terms both models share on the same states cancel exactly."""
    out = np.zeros(n)
    for name in dict.fromkeys(list(actual) + list(reference)):
        out += actual.get(name, 0.0) - reference.get(name, 0.0)
    return out


def flown_with(campaign) -> dict:
    """What a simulated campaign was flown with (``withheld``, ``anomaly``, ``simulated_aircraft``...): its
    ``extra``, or, for a campaign read from disk (whose reader keeps no extra keys), the top-level keys
    of its ``campaign.toml``."""
    if campaign.extra or campaign.directory is None:
        return dict(campaign.extra)
    from ..data.errors import StructSearchError
    from ..data.reading import load_toml
    try:
        doc = load_toml(Path(campaign.directory) / "campaign.toml")
    except (OSError, StructSearchError):   # the campaign reader already refused or accepted it, by name
        return {}
    return {k: v for k, v in doc.items() if not isinstance(v, (dict, list))}


def _withheld_of(extra) -> list[str]:
    text = str(extra.get("withheld", "none"))
    return [w for w in text.split(",") if w and w != "none"]


def effect_coefficient(effect: str) -> str:
    """The coefficient an effect (withholdable or anomaly) belongs to."""
    if effect in ANOMALIES:
        return ANOMALIES[effect].coefficient
    if effect in EFFECT_COEFFICIENT:
        return EFFECT_COEFFICIENT[effect]
    raise DeclarationError(f"no effect {effect!r}: effects of the final model are {', '.join(EFFECT_COEFFICIENT)}; "
                           f"anomalies are {', '.join(ANOMALIES)}")


def truth_difference(campaign, effect: str, coefficient: str | None = None) -> np.ndarray:
    """Per sample of ``campaign.data``: how much of ``coefficient`` (default: the effect's own) ``effect`` explains.

    Sign convention: C(truth the campaign was flown with) - C(the same truth toggled in ``effect``),
    both evaluated on the flown (measured) states: what a model that differs from the campaign's
    truth only in ``effect`` misses, i.e. the part of the data the effect accounts for.

    - default campaign (nothing withheld, no anomaly), withholdable ``effect``: ``truth_model()`` minus
      ``truth_model([effect])`` (the withheld-effect benchmark: the data have it, the baseline lacks it);
    - campaign flown with ``effect`` withheld: ``truth_model([effect])`` minus ``truth_model()`` (the data
      lack it; a model with it misses this, with the opposite sign);
    - anomaly campaign, ``effect`` its anomaly: the truth with the anomaly minus the final truth. For
      ``vane_lag`` (a measurement error): the final truth on the alpha the chain reads without the lag
      (column ``alpha_unlagged_true``, its alpha_dot differentiated as the chain does) minus the final truth
      on the recorded, lagged alpha, plus the change of the reconstructed C_L and C_D from rotating the
      body-axis forces with the lagged alpha (C_m is not rotated).

    What the campaign was flown with comes from :func:`flown_with`. "Flown states": the campaign's
    measured alpha, alpha_dot, q, V, de, CT, x_cg, h; each model's separation states run over each
    maneuver's alpha history from equilibrium at its first sample (:func:`flown_states`). Terms the two
    models share on the same states cancel exactly (zero where the effect cannot act). For pullups and
    pushovers, cut where the pilot recovers, the unlagged alpha_dot of ``vane_lag`` differs from the
    chain's at the last sample (differentiated on the cut record).
    """
    extra = flown_with(campaign)
    aircraft = str(extra.get("simulated_aircraft", "citation"))
    withheld = _withheld_of(extra)
    flown_anomaly = extra.get("anomaly")
    coef = coefficient or effect_coefficient(effect)
    if coef not in LONGITUDINAL:
        raise DeclarationError(f"no coefficient {coef!r}: truth differences are of {', '.join(LONGITUDINAL)}")
    data = campaign.data
    if effect in ANOMALIES:
        if flown_anomaly != effect:
            raise DeclarationError(f"the campaign {campaign.name!r} was not flown with the anomaly {effect!r}"
                                   + (f" (it was flown with {flown_anomaly!r})" if flown_anomaly else ""))
        anomaly = ANOMALIES[effect]
        if not anomaly.flies:
            return _vane_lag_difference(data, coef, truth_model(withheld, aircraft))
        actual = truth_model(withheld, aircraft, anomaly)
        reference = truth_model(withheld, aircraft)
    else:
        effect_coefficient(effect)  # unknown effects raise
        anomaly = anomaly_named(str(flown_anomaly)) if flown_anomaly else None
        flying = anomaly if anomaly is not None and anomaly.flies else None
        toggled = [w for w in withheld if w != effect] if effect in withheld else withheld + [effect]
        actual = truth_model(withheld, aircraft, flying)
        reference = truth_model(toggled, aircraft, flying)
    return _difference(flown_terms(actual, data, coef), flown_terms(reference, data, coef), data.n_samples)


def _vane_lag_difference(data, coef: str, model: AeroModel) -> np.ndarray:
    if "alpha_unlagged_true" not in data:
        raise DeclarationError("the vane_lag difference needs the column alpha_unlagged_true (campaigns built with "
                               "anomaly='vane_lag' carry it)")
    unlagged = data["alpha_unlagged_true"]
    unlagged_dot = np.concatenate([derivative(unlagged[sl], data["t"][sl]) for sl in data.segment_slices()])
    out = _difference(flown_terms(model, data, coef, unlagged, unlagged_dot), flown_terms(model, data, coef),
                      data.n_samples)
    if coef != "Cm" and "CX" in data and "CZ" in data:
        a, cx, cz = data["alpha"], data["CX"], data["CZ"]
        if coef == "CL":
            out += (cx * np.sin(a) - cz * np.cos(a)) - (cx * np.sin(unlagged) - cz * np.cos(unlagged))
        else:
            out += (-cx * np.cos(a) - cz * np.sin(a)) - (-cx * np.cos(unlagged) - cz * np.sin(unlagged))
    return out
