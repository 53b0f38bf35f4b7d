"""Static separation curves X0(alpha): the forms a separation state's static characteristic may take.

Every form is non-increasing in alpha, has its values in [0, 1] (1: attached flow) whatever its parameters
inside their boxes (:mod:`structsearch.data.default_boxes`), and comes with its exact derivatives in alpha and in
its parameters. Parameter names are base names; a state suffixes them with its name (``k_e_ss``).

``tanh`` (the thesis' curve, the default)::

    X0 = 0.5 (1 - tanh(a1 (alpha - a_star)))

``goman`` (exponential; parameters ``a_star``, ``k_e``, ``x_star``)::

    X0 = x_star exp(-k_e (alpha - a_star))                          alpha >= a_star
    X0 = 1 - (1 - x_star) exp(k_b (alpha - a_star)),  k_b = k_e x_star / (1 - x_star)   alpha < a_star

  The exponential decay of the separation point beyond the break that Goman and Khrabrov's lag is fitted
  with in the stall literature (Beddoes-Leishman's two exponentials of Kirchhoff's f), joined at the break so
  that the value (x_star) and the slope (-k_e x_star) agree: the curve is C1 in alpha and in its parameters;
  its second derivative jumps at alpha = a_star (the only non-smooth point; a least-squares solver needs C1).
  Its limit x_star -> 1 is the hard form X0 = 1 before the break, exp(-k_e (alpha - a_star)) beyond, which
  has a kink; the box of x_star stops short of 1 for that reason.

``two_break`` (two logistic breaks around a plateau; ``k1``, ``a_k1``, ``k2``, ``da_k2``, ``x_mid``)::

    X0 = (1 - x_mid) s(k1, a_k1) + x_mid s(k2, a_k1 + da_k2),   s(k, a) = 0.5 (1 - tanh(k (alpha - a)))

  The flow falls from 1 to the plateau x_mid at the first break a_k1 and from x_mid to 0 at the second,
  da_k2 >= 0 beyond it (the order is a parameter bound, so the two breaks never swap). Smooth (C-infinity).

``spline:K`` (a monotone quadratic spline with K free knots; ``a_sp``, ``h_sp``, ``r1`` ... ``rK``)::

    X0 = sum_j c_j N((alpha - a_sp) / h_sp - j),  c_j = 1 (j <= 0),  c_j = r1 r2 ... rj (1 <= j <= K),
    c_j = c_K (j > K)

  N is the centred uniform quadratic B-spline (support [-1.5, 1.5]), so knot j sits at a_sp + j h_sp. With
  every ratio r_j in [0, 1] the coefficients are non-increasing in [0, 1], hence X0 is too (a B-spline's
  values are convex combinations of its coefficients and it inherits their monotonicity): the bounds alone
  guarantee a monotone curve in [0, 1]. X0 = 1 before a_sp - h_sp/2 and c_K (a separated-flow floor) after
  a_sp + (K + 1/2) h_sp; C1 in alpha and in the parameters, its second derivative jumps at the half-knots.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np
from scipy.special import expit

from ..data.default_boxes import MAX_SPLINE_KNOTS, TIME_BOUNDS, TIME_STARTS
from ..data.errors import DeclarationError

# The units of a form's parameters (base unit -> exponent; {} dimensionless)
ANGLE, PER_ANGLE, NUMBER = {"rad": 1}, {"rad": -1}, {}


@dataclass(frozen=True)
class StaticForm:
    """One static separation curve X0(alpha): everything the project knows of it, in one record.

    ``parameters`` are base names (a state suffixes them); a ``knotted`` form (``name:K``) adds K ratios
    ``r1`` ... ``rK`` after them. ``boxes`` and ``starts`` are the default search box and start of every
    parameter (set on the Citation II's stall, widened to the data: :func:`~structsearch.data.default_boxes.data_bounds`),
    ``units`` their units, ``locations`` the angles where the curve sits (widened to the alpha range flown, never
    t-tested against zero), ``steepness`` its slopes and offsets (not t-tested either: see
    :data:`CURVE_SHAPE_PARAMETERS`). ``meaning`` is the "where" line of the equations (empty for the tanh, which
    they write in full). ``curve(alpha, values, derivatives, knots)`` returns X0, dX0/dalpha and dX0/dparameters.
    ``exported``: the JSBSim export writes it."""

    name: str
    parameters: tuple[str, ...]
    curve: Callable
    boxes: Mapping[str, tuple[float, float]]
    starts: Mapping[str, float]
    units: Mapping[str, Mapping[str, int]]
    locations: tuple[str, ...]
    steepness: tuple[str, ...]
    meaning: str = ""
    knotted: bool = False
    exported: bool = False

    def parameters_of(self, knots: int | None = None) -> tuple[str, ...]:
        """The base names of its parameters (with ``knots`` ratios for a knotted form), in a state's order."""
        return self.parameters + tuple(f"r{j}" for j in range(1, (knots or 0) + 1))

    @property
    def declared(self) -> str:
        """How a spec names it (``spline:K`` for a knotted form)."""
        return f"{self.name}:K" if self.knotted else self.name


def parse_form(form) -> tuple[StaticForm, int | None]:
    """The registered form ``form`` names and its number of knots (None for a form without), else one
    DeclarationError naming it and the close match."""
    name, _, knots = str(form).partition(":") if isinstance(form, str) else ("", "", "")
    entry = FORMS.get(name)
    if entry is not None and entry.knotted and knots:
        if knots.isdigit() and 2 <= int(knots) <= MAX_SPLINE_KNOTS and str(int(knots)) == knots:
            return entry, int(knots)
        raise DeclarationError(f"static separation form {form!r}: K of {name}:K is a whole number of knots "
                               f"from 2 to {MAX_SPLINE_KNOTS}, not {knots!r}")
    if entry is not None and not entry.knotted and form == name:
        return entry, None
    examples = [f.name + (":4" if f.knotted else "") for f in FORMS.values()]
    close = difflib.get_close_matches(str(form), examples, n=1, cutoff=0.5)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise DeclarationError(f"static separation form {form!r} is not one of {', '.join(FORM_NAMES)}{hint}")


def check_form(form) -> str:
    """``form`` if it names a registered static separation form (a knotted one as ``name:K``, K in
    2..MAX_SPLINE_KNOTS), else one DeclarationError naming it and the close match."""
    parse_form(form)
    return form


def spline_knots(form: str) -> int:
    return parse_form(form)[1] or 0


def form_parameters(form: str) -> tuple[str, ...]:
    """The base names of the parameters of ``form``, in their order in a state's parameters."""
    entry, knots = parse_form(form)
    return entry.parameters_of(knots)


def static_value(form: str, alpha, values) -> np.ndarray:
    """X0(alpha) of ``form`` with its parameters' ``values`` (base name -> number)."""
    return static_gradient(form, alpha, values, False)[0]


def static_gradient(form: str, alpha, values, derivatives: bool = True):
    """X0(alpha), dX0/dalpha and dX0/dparameters (n, p), in :func:`form_parameters` order (the last two None
    without ``derivatives``)."""
    alpha = np.asarray(alpha, float)
    shape = alpha.shape
    entry, knots = parse_form(form)
    x0, dalpha, grads = entry.curve(alpha.ravel(), values, derivatives, knots)
    if not derivatives:
        return x0.reshape(shape), None, None
    return x0.reshape(shape), dalpha.reshape(shape), grads.reshape(shape + (grads.shape[-1],))


def tanh_curve(alpha, a1, a_star):
    """X0 = 0.5 (1 - tanh(a1 (alpha - a_star))), written as a logistic so it never rounds to 0."""
    return expit(-2.0 * a1 * (np.asarray(alpha) - a_star))


def _tanh(alpha, v, derivatives, knots=None):
    a1, a_star = v["a1"], v["a_star"]
    x0 = tanh_curve(alpha, a1, a_star)
    if not derivatives:
        return x0, None, None
    slope = -2.0 * x0 * (1.0 - x0)
    return x0, slope * a1, np.column_stack([slope * (alpha - a_star), slope * (-a1)])


def _goman(alpha, v, derivatives, knots=None):
    a_star, k, xs = v["a_star"], v["k_e"], v["x_star"]
    d = alpha - a_star
    above = d >= 0.0
    kb = k * xs / (1.0 - xs)
    e_above = np.exp(-k * np.maximum(d, 0.0))        # <= 1: never overflows
    e_below = np.exp(kb * np.minimum(d, 0.0))
    x0 = np.where(above, xs * e_above, 1.0 - (1.0 - xs) * e_below)
    if not derivatives:
        return x0, None, None
    e = np.where(above, e_above, e_below)
    dalpha = -k * xs * e                             # the same expression on both sides: C1 at the break
    dk = -xs * e * d
    dxs = np.where(above, e_above, e_below * (1.0 - d * k / (1.0 - xs)))
    return x0, dalpha, np.column_stack([-dalpha, dk, dxs])


def _two_break(alpha, v, derivatives, knots=None):
    k1, a_k1, k2, da_k2, xm = v["k1"], v["a_k1"], v["k2"], v["da_k2"], v["x_mid"]
    d1, d2 = alpha - a_k1, alpha - a_k1 - da_k2
    s1, s2 = expit(-2.0 * k1 * d1), expit(-2.0 * k2 * d2)
    x0 = (1.0 - xm) * s1 + xm * s2
    if not derivatives:
        return x0, None, None
    g1, g2 = (1.0 - xm) * (-2.0 * s1 * (1.0 - s1)), xm * (-2.0 * s2 * (1.0 - s2))
    dalpha = g1 * k1 + g2 * k2
    grads = np.column_stack([g1 * d1, -g1 * k1 - g2 * k2, g2 * d2, -g2 * k2, s2 - s1])
    return x0, dalpha, grads


def spline_coefficients(ratios: np.ndarray) -> np.ndarray:
    """c_0 = 1, c_j = r_1 ... r_j (j = 1..K)."""
    return np.concatenate([[1.0], np.cumprod(ratios)])


def _spline(alpha, v, derivatives, k):
    a0, h = v["a_sp"], v["h_sp"]
    r = np.array([v[f"r{j}"] for j in range(1, k + 1)], float)
    c = spline_coefficients(r)
    u = (alpha - a0) / h
    m = np.floor(u + 0.5)
    t = u - m
    w = ((0.5 - t) ** 2 / 2.0, 0.75 - t * t, (0.5 + t) ** 2 / 2.0)   # weights of c_{m-1}, c_m, c_{m+1}
    index = [np.clip(m + o, 0, k).astype(np.int64) for o in (-1, 0, 1)]
    # the weights sum to 1 up to rounding: clipped so that no value leaves [0, 1] by an ulp
    x0 = np.clip(sum(wi * c[ii] for wi, ii in zip(w, index)), 0.0, 1.0)
    if not derivatives:
        return x0, None, None
    du = -(0.5 - t) * c[index[0]] - 2.0 * t * c[index[1]] + (0.5 + t) * c[index[2]]
    weights = np.zeros((len(alpha), k + 1))     # dX0/dc_j (the clipped indices add up: c_j = c_0 or c_K)
    rows = np.arange(len(alpha))
    for wi, ii in zip(w, index):
        np.add.at(weights, (rows, ii), wi)
    # dc_j/dr_i = prod_{l <= j, l != i} r_l for j >= i (a product without r_i: exact at r_i = 0 too)
    dc = np.zeros((k + 1, k))
    for i in range(k):
        others = r.copy()
        others[i] = 1.0
        dc[i + 1:, i] = np.cumprod(others)[i:]
    grads = np.column_stack([du * (-1.0 / h), du * (-u / h), weights @ dc])
    return x0, du / h, grads


# ----- the registry -------------------------------------------------------------------------------------------
RATIOS = tuple(f"r{j}" for j in range(1, MAX_SPLINE_KNOTS + 1))
# The boxes: the Citation II's stall (docs/catalogue.md "separation parameters"); rates per rad, angles in rad.
# A spline ratio in [0, 1] is what keeps the spline monotone; x_star stops short of 0 and 1, where goman's slope
# below the break would vanish or become infinite.
TANH = StaticForm("tanh", ("a1", "a_star"), _tanh, {"a1": (2.0, 200.0), "a_star": (0.05, 0.45)},
                  {"a1": 30.0, "a_star": 0.25}, {"a1": PER_ANGLE, "a_star": ANGLE}, ("a_star",), ("a1",),
                  exported=True)
GOMAN = StaticForm(
    "goman", ("a_star", "k_e", "x_star"), _goman, {"a_star": (0.05, 0.45), "k_e": (2.0, 200.0), "x_star": (0.05, 0.95)},
    {"a_star": 0.25, "k_e": 30.0, "x_star": 0.5}, {"a_star": ANGLE, "k_e": PER_ANGLE, "x_star": NUMBER}, ("a_star",),
    ("k_e",), "X0_goman(a; a_star, k_e, x_star) = x_star*exp(-k_e*(a - a_star)) for a >= a_star, "
              "1 - (1 - x_star)*exp(k_e*x_star/(1 - x_star)*(a - a_star)) below")
TWO_BREAK = StaticForm(
    "two_break", ("k1", "a_k1", "k2", "da_k2", "x_mid"), _two_break,
    {"k1": (2.0, 200.0), "a_k1": (0.05, 0.45), "k2": (2.0, 200.0), "da_k2": (0.0, 0.3), "x_mid": (0.0, 1.0)},
    {"k1": 30.0, "a_k1": 0.2, "k2": 30.0, "da_k2": 0.08, "x_mid": 0.5},
    {"k1": PER_ANGLE, "a_k1": ANGLE, "k2": PER_ANGLE, "da_k2": ANGLE, "x_mid": NUMBER}, ("a_k1",),
    ("k1", "k2", "da_k2"), "X0_two_break(a; k1, a_k1, k2, da_k2, x_mid) = (1 - x_mid)*0.5*(1 - tanh(k1*(a - a_k1))) "
                           "+ x_mid*0.5*(1 - tanh(k2*(a - a_k1 - da_k2)))")
SPLINE = StaticForm(
    "spline", ("a_sp", "h_sp"), _spline,
    {"a_sp": (0.05, 0.45), "h_sp": (0.005, 0.1), **{r: (0.0, 1.0) for r in RATIOS}},
    {"a_sp": 0.15, "h_sp": 0.04, **{r: 0.6 for r in RATIOS}}, {"a_sp": ANGLE, "h_sp": ANGLE, **{r: NUMBER for r in RATIOS}},
    ("a_sp",), (), "X0_spline(a; a_sp, h_sp, r1..rK) = sum_j c_j*N((a - a_sp)/h_sp - j), c_j = 1 (j <= 0), "
                   "r1*...*rj (1 <= j <= K), c_K (j > K), N the centred quadratic B-spline", knotted=True)
FORMS: Mapping[str, StaticForm] = {f.name: f for f in (TANH, GOMAN, TWO_BREAK, SPLINE)}
FORM_NAMES = tuple(f.declared for f in FORMS.values())
DEFAULT_FORM = TANH.name
EXPORTED_FORMS = tuple(f.name for f in FORMS.values() if f.exported)
TANH_PARAMETERS, GOMAN_PARAMETERS, TWO_BREAK_PARAMETERS = TANH.parameters, GOMAN.parameters, TWO_BREAK.parameters
# The angles of attack where a static curve sits (its break, its first knot): a t-test of one against zero tests
# the datum of alpha, not the data; the rule that it lies inside the alpha range flown judges it instead.
LOCATION_PARAMETERS = tuple(dict.fromkeys(p for f in FORMS.values() for p in f.locations))
# Where a static curve breaks and how steeply (the break angles above; slopes and the second break's offset).
# None is t-tested against zero: a location's zero is alpha's datum, and a slope's Wald interval is not its
# uncertainty (the cost is far from quadratic in the slope of a sharp break, a measured p = 0.38 for a slope of
# 48/rad whose flat limit, 0, fits 13 times worse on the NACA section); whether the data need the curve at all is
# asked by removing its state (the refinement's move), whether they place it by its box and the alpha range flown.
CURVE_SHAPE_PARAMETERS = LOCATION_PARAMETERS + tuple(dict.fromkeys(p for f in FORMS.values() for p in f.steepness))
# Every separation parameter's default box and start: the time constants' and every form's.
SEPARATION_BOUNDS = {**TIME_BOUNDS, **{p: box for f in FORMS.values() for p, box in f.boxes.items()}}
SEPARATION_STARTS = {**TIME_STARTS, **{p: v for f in FORMS.values() for p, v in f.starts.items()}}
