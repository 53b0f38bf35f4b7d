"""Flow-separation states (Kirchhoff / Goman-Khrabrov) and their parameter sensitivities.

    X0(a; a1, a_star) = 0.5 * (1 - tanh(a1 * (a - a_star)))
    tau1 * dX/dt + X = X0(alpha - tau2 * alpha_dot)

X0 above is the default static curve (form ``tanh``); a state may take another form of
:mod:`.static_forms` (``goman``, ``two_break``, ``spline:K``), whose parameters replace a1 and a_star.

Five kinds: steady ``S`` (X = X0(alpha)), quasi-steady ``Q`` (X = X0(alpha -
tau2*alpha_dot)), unsteady ``U`` (first-order lag of the quasi-steady value), lagged ``L`` (a first-order lag
of X0(alpha) without the alpha_dot delay: U with tau2 = 0, the state a pitching airfoil's data often support
when tau2 and tau1 cannot be told apart) and vortex ``V``: the strength of the dynamic-stall vortex,

    tau1 * dXs/dt + Xs = X0(alpha)        (the flow separating, as L)
    tau_v * dY/dt + Y = Xs,   V = Y - Xs  (what separated lately and has not convected away)

V grows while the flow separates faster than the vortex convects (Xs falling), peaks, and decays with tau_v once
the separation stops: the lift overshoot and collapse of deep dynamic stall, the vortex lift that the
Beddoes-Leishman model adds as a high-pass of its circulatory lift deficit and decays with its vortex time
constant. V is linear in Xs, so its sensitivities follow through the same two lags; it is zero in steady flow.

The lag is discretised exactly for an input that is linear between samples
(first-order hold), on any strictly increasing time grid. Every maneuver starts
in equilibrium with its first sample, X(t0) = X0(alpha0 - tau2*alpha_dot0), so a
state never runs across a maneuver boundary; a periodic maneuver (a pitching airfoil's
cycle) starts at its periodic solution instead (:func:`first_order_lag`). Sensitivities
dX/dtheta are propagated through the same recursion, which is linear in the state.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.signal import lfilter

from ..data.errors import DeclarationError
from ..data.flightdata import derivative
from .static_forms import DEFAULT_FORM, check_form, form_parameters, static_gradient, tanh_curve

from .state_kinds import (KINDS, PARAMETERS_OF_KIND, TIME_PARAMETERS_OF_KIND, is_delayed, is_lagged,  # noqa: F401
                          is_vortex, nests)


def vortex_symbols(states) -> frozenset[str]:
    """The symbols of the vortex states among ``states`` ((name, kind) pairs)."""
    return frozenset(SeparationState(n, k).symbol for n, k in states if is_vortex(k))


# A step of a uniform grid may differ from the first by this relative amount.
_UNIFORM_RTOL = 1e-9
# Largest log-decay inside one block of the time-varying recursion (small blocks keep the
# cumulative sums accurate to ~1e-14; the loop is over blocks, not samples).
_BLOCK_DECAY = 50.0


@dataclass(frozen=True)
class SeparationState:
    """One separation state: ``name`` "ss" gives symbol ``X_ss`` and parameters ``tau1_ss``...

    An empty name gives symbol ``X`` and parameters ``tau1, tau2, a1, a_star``. ``form`` is its static curve
    X0 (:mod:`.static_forms`; "tanh", the default, has a1 and a_star), whose parameters follow the kind's time
    constants. ``drive``: the state reads alpha + drive p* (p* = p b / (2 V)) in place of alpha, a wing's own
    angle of attack (a wing at ``drive`` half spans to the right of the plane of symmetry; 0: the aircraft's).
    """

    name: str
    kind: str
    form: str = DEFAULT_FORM
    drive: float = 0.0

    def __post_init__(self):
        if self.kind not in KINDS:
            raise DeclarationError(f"separation state {self.symbol!r}: kind {self.kind!r} is not one of {KINDS}")
        if self.name and not self.name.isidentifier():
            raise DeclarationError(f"separation state name {self.name!r} is not an identifier")
        try:
            check_form(self.form)
        except DeclarationError as exc:
            raise DeclarationError(f"separation state {self.symbol!r}: {exc}") from None

    @property
    def symbol(self) -> str:
        return f"X_{self.name}" if self.name else "X"

    @property
    def base_parameters(self) -> tuple[str, ...]:
        return TIME_PARAMETERS_OF_KIND[self.kind] + form_parameters(self.form)

    @property
    def parameters(self) -> tuple[str, ...]:
        return tuple(self.parameter_name(p) for p in self.base_parameters)

    def parameter_name(self, base: str) -> str:
        return f"{base}_{self.name}" if self.name else base


# X0 of the tanh form, the thesis' curve (one definition: :func:`.static_forms.tanh_curve`)
static_separation = tanh_curve


def _lag_coefficients(dt: np.ndarray, tau1: float):
    """Coefficients of X_k = a X_{k-1} + b0 u_{k-1} + b1 u_k and their tau1-derivatives. At tau1 = 0 (the
    quasi-steady state a lag nests) their limits: X = u, dX/dtau1 = -(u_k - u_{k-1}) / dt."""
    dt = np.asarray(dt, float)
    if tau1 == 0.0:
        zero, one = np.zeros_like(dt), np.ones_like(dt)
        return zero, zero, one, zero, one / dt, -one / dt
    x = dt / tau1
    a = np.exp(-x)
    one_minus_a = -np.expm1(-x)
    g = one_minus_a / x
    da = a * x / tau1
    dg = one_minus_a / dt - a / tau1
    return a, g - a, 1.0 - g, da, dg - da, -dg


def _is_uniform(dt: np.ndarray) -> bool:
    return bool(np.all(np.abs(dt - dt[0]) <= _UNIFORM_RTOL * dt[0]))


def linear_recurrence(a: np.ndarray, f: np.ndarray, y0) -> np.ndarray:
    """Solve y_0 = y0, y_k = a_k y_{k-1} + f_k (k >= 1) without a loop over samples.

    ``a`` has length n (a[0] unused, every a_k in (0, 1]); ``f`` has shape (n,) or
    (n, p). The closed form y_k = P_k (y0 + sum_j f_j / P_j) with P the running
    product of ``a`` is evaluated in blocks over which P falls by at most e^-50,
    so nothing under- or overflows; only the block carries are sequential.
    """
    f = np.asarray(f, dtype=float)
    y = np.empty_like(f)
    n = len(a)
    y[0] = y0
    if n == 1:
        return y
    with np.errstate(divide="ignore"):
        log_a = np.log(a)  # -inf where a step is so long (dt > ~745 tau1) that the state forgets all
    # A step that alone decays by more than e^-BLOCK starts a block of its own, where the sequential
    # formula below uses a_k itself (0 included); clipping keeps the running sum finite.
    log_p = np.concatenate([[0.0], np.cumsum(np.maximum(log_a[1:], -2.0 * _BLOCK_DECAY))])
    block = np.floor(-log_p / _BLOCK_DECAY).astype(np.int64)
    edges = np.flatnonzero(np.diff(block)) + 1
    starts = np.concatenate([[1], edges[edges > 1]])
    stops = np.append(starts[1:], n)
    expand = (slice(None),) + (None,) * (f.ndim - 1)
    for s, e in zip(starts, stops):
        # summed inside the block: differences of the global running sum lose ~1e-12
        rel = np.concatenate([[0.0], np.cumsum(log_a[s + 1:e])])
        y_s = a[s] * y[s - 1] + f[s]
        y[s] = y_s
        if e > s + 1:
            acc = np.cumsum(f[s + 1:e] * np.exp(-rel[1:])[expand], axis=0)
            y[s + 1:e] = np.exp(rel[1:])[expand] * (y_s + acc)
    return y


def common_step(t: np.ndarray, bounds: np.ndarray) -> float | None:
    """The sample step if every maneuver has the same uniform step, else None."""
    dt = np.diff(t)
    inside = np.ones(len(dt), bool)
    inside[bounds[1:-1] - 1] = False  # steps across maneuver boundaries do not count
    steps = dt[inside]
    if steps.size == 0 or not _is_uniform(steps):
        return None
    return float(steps[0])


@lru_cache(maxsize=64)
def _segment_heads(bounds_bytes: bytes, length: int):
    """Indices of the first ``length`` samples of every maneuver, their offsets and maneuver numbers."""
    bounds = np.frombuffer(bounds_bytes, dtype=np.int64)
    starts, sizes = bounds[:-1], np.diff(bounds)
    offset = np.arange(length)
    keep = offset[None, :] < sizes[:, None]
    index = (starts[:, None] + offset[None, :])[keep]
    segment = np.broadcast_to(np.arange(len(starts))[:, None], keep.shape)[keep]
    offsets = np.broadcast_to(offset[None, :], keep.shape)[keep].astype(float)
    for a in (index, segment, offsets):
        a.flags.writeable = False
    return index, segment, offsets


# Beyond this many time constants a^(k-s) < 1e-18: the boundary correction has vanished.
_CORRECTION_TAUS = 41.5


def _lag_common_step(t, u, du, tau1, bounds, step):
    """All maneuvers on one uniform grid: filter the whole record at once, then correct.

    Filtering across a boundary only changes the state at the maneuver's first
    sample; by linearity the difference then decays as a^(k-s), so subtracting
    a^(k-s) (X'_s - u_s) restores X_s = u_s exactly. The correction is applied
    only where it has not yet decayed below 1e-18. The same holds for the
    sensitivities.
    """
    a, b0, b1, da, db0, db1 = (float(v[0]) for v in _lag_coefficients(np.array([step]), tau1))
    starts = bounds[:-1]
    length = int(min(np.ceil(_CORRECTION_TAUS * tau1 / step) + 1, np.max(np.diff(bounds))))
    index, segment, offsets = _segment_heads(bounds.tobytes(), length)
    decay = np.exp(offsets * (-step / tau1)) if tau1 > 0 else (offsets == 0).astype(float)
    x = lfilter([b1, b0], [1.0, -a], u)
    x[index] -= decay * (x[starts] - u[starts])[segment]
    if du is None:
        return x, None, None
    dx = lfilter([b1, b0], [1.0, -a], du, axis=0)
    dx[index] -= decay[:, None] * (dx[starts] - du[starts])[segment]
    forcing = np.empty_like(u)
    forcing[1:] = da * x[:-1] + db0 * u[:-1] + db1 * u[1:]
    forcing[starts] = 0.0
    dtau = lfilter([1.0], [1.0, -a], forcing)
    dtau[index] -= decay * dtau[starts][segment]
    return x, dx, dtau


# A lag shorter than this (s) is its tau1 -> 0 limit: X = u, dX/dtau1 = -(u_k - u_{k-1}) / dt (the error is
# tau1 / dt of one sample's change). tau1 -> 0 is where an unsteady state nests the quasi-steady one, and the
# optimiser's start just inside a box that begins at 0 lies here.
INSTANT_LAG = 1e-9


def _instant_lag(t, u, du, bounds):
    x = np.array(u, float, copy=True)
    if du is None:
        return x, None, None
    dtau = np.zeros_like(x)
    dtau[1:] = -np.diff(x) / np.diff(t)
    dtau[bounds[:-1]] = 0.0          # every maneuver starts at X = u
    return x, np.array(du, float, copy=True), dtau


def first_order_lag(t: np.ndarray, u: np.ndarray, du: np.ndarray, tau1: float,
                    bounds: np.ndarray, step: float | None | bool = False, periods=None):
    """tau1 dX/dt + X = u on every maneuver, each starting at X = u(t0), or a periodic one at its periodic solution.

    ``du`` (n, p) holds du/dtheta for the parameters inside u; returns ``X`` (n,),
    ``dX`` (n, p) = dX/dtheta and ``dX_dtau1`` (n,); with ``du`` None, only ``X`` (the others None). ``step`` may pass in the
    result of :func:`common_step` for this grid (it is found here otherwise). ``periods``: per maneuver its period
    T [s] where it is periodic, infinite where its samples are steady points (each its own equilibrium: X = u, no
    dependence on tau1), NaN (or None) where neither (None: no maneuver is either); see :func:`_periodic_start`.
    """
    bounds = np.asarray(bounds, dtype=np.int64)
    periodic = _periodic_segments(periods, len(bounds) - 1)
    out = _lag_from_equilibrium(t, u, du, tau1, bounds, step)
    for i, period in periodic:
        if np.isinf(period):
            _steady(u, du, int(bounds[i]), int(bounds[i + 1]), *out)
        else:
            _periodic_start(t, u, du, tau1, int(bounds[i]), int(bounds[i + 1]), period, *out)
    return out


def _steady(u, du, s, e, x, dx, dtau) -> None:
    """Maneuver ``s:e`` as steady points, in place: the lag's equilibrium X = u at every sample (the limit of an
    infinitely slow cycle), its sensitivities those of u, none to tau1. Its samples' times order them only."""
    x[s:e] = u[s:e]
    if du is not None:
        dx[s:e] = du[s:e]
        dtau[s:e] = 0.0


def _periodic_segments(periods, n_segments: int) -> list[tuple[int, float]]:
    """(maneuver index, period) of every periodic maneuver and every maneuver of steady points (period inf)."""
    if periods is None:
        return []
    periods = np.asarray(periods, dtype=float)
    if periods.shape != (n_segments,):
        raise ValueError(f"{periods.shape[0] if periods.ndim else 'no'} periods for {n_segments} maneuvers")
    return [(int(i), float(periods[i])) for i in np.flatnonzero(~np.isnan(periods))]


def _periodic_start(t, u, du, tau1, s, e, period, x, dx, dtau) -> None:
    """Move the state of maneuver ``s:e`` (and its sensitivities), computed from X(t0) = u0, in place to its
    periodic solution: the start X(t0) = X(t0 + T).

    Why this is exact: the lag is linear, so X = Y + c P_k with Y the solution from Y(t0) = u0 and P_k =
    exp(-(t_k - t0)/tau1) the free response. One period maps a start X0 to Phi X0 + r with Phi = exp(-T/tau1)
    (the product of every step's a over the period); X0 = r / (1 - Phi) is the periodic start, so c = X0 - u0 =
    (Y(t0 + T) - u0) / (1 - Phi). The input at t0 + T is the record's own, linear between samples (first-order
    hold), when the record runs past one period; a record of one cycle (t0 + T after its last sample) wraps:
    u(t0 + T) = u(t0). Y(t0 + T) is one step of the same discretisation from the last sample at or before t0 + T.
    The sensitivities differentiate c: dc/dtheta through Y(t0 + T) and u0, dc/dtau1 also through Phi, and
    dP_k/dtau1 = P_k (t_k - t0) / tau1^2.
    """
    ts = t[s:e]
    t_end = ts[0] + period
    j = s + int(np.searchsorted(ts, t_end, side="right")) - 1
    h = float(t_end - t[j])
    if j == e - 1:   # one cycle: the input wraps to the first sample
        w, nxt = 1.0, s
    else:
        w, nxt = h / float(t[j + 1] - t[j]), j + 1
    u_end = (1.0 - w) * u[j] + w * u[nxt]
    du_end = None if du is None else (1.0 - w) * du[j] + w * du[nxt]
    if tau1 < INSTANT_LAG:   # X = u: the start is the input one period later, dX/dtau1 its limit
        x[s] = u_end
        if du is not None:
            dx[s] = du_end
            dtau[s] = -(u_end - u[j]) / h if h > 0 else dtau[j]
        return
    if h > 0:
        a, b0, b1, da, db0, db1 = (float(v[0]) for v in _lag_coefficients(np.array([h]), tau1))
    else:   # t0 + T is the last sample itself
        a, b0, b1, da, db0, db1 = 1.0, 0.0, 0.0, 0.0, 0.0, 0.0
    one_minus_phi = -np.expm1(-period / tau1)
    c = (a * x[j] + b0 * u[j] + b1 * u_end - u[s]) / one_minus_phi
    elapsed = ts - ts[0]
    free = np.exp(-elapsed / tau1)
    if du is not None:
        dc = (a * dx[j] + b0 * du[j] + b1 * du_end - du[s]) / one_minus_phi
        dphi = np.exp(-period / tau1) * period / tau1 ** 2
        dc_dtau = (da * x[j] + a * dtau[j] + db0 * u[j] + db1 * u_end) / one_minus_phi + c * dphi / one_minus_phi
        dx[s:e] += free[:, None] * dc[None, :]
        dtau[s:e] += free * (dc_dtau + c * elapsed / tau1 ** 2)
    x[s:e] += c * free


def _lag_from_equilibrium(t, u, du, tau1, bounds, step):
    """:func:`first_order_lag` with every maneuver starting at X = u(t0)."""
    if tau1 < INSTANT_LAG:
        return _instant_lag(t, u, du, bounds)
    if step is False:
        step = common_step(t, bounds)
    if step is not None:
        return _lag_common_step(t, u, du, tau1, bounds, step)
    x_out = np.empty_like(u)
    dx_out = np.empty_like(du) if du is not None else None
    dtau_out = np.empty_like(u) if du is not None else None
    for i in range(len(bounds) - 1):
        s, e = int(bounds[i]), int(bounds[i + 1])
        ts, us = t[s:e], u[s:e]
        dt = np.diff(ts)
        a, b0, b1, da, db0, db1 = _lag_coefficients(dt, tau1)
        if du is None:  # the value alone, by the same branch as below
            if _is_uniform(dt):
                x_out[s:e] = lfilter([b1[0], b0[0]], [1.0, -a[0]], us, zi=[(1.0 - b1[0]) * us[0]])[0]
            else:
                drive = np.zeros_like(us)
                drive[1:] = b0 * us[:-1] + b1 * us[1:]
                x_out[s:e] = linear_recurrence(np.concatenate([[1.0], a]), drive, us[0])
            continue
        dus = du[s:e]
        if _is_uniform(dt):
            a0, b00, b10 = a[0], b0[0], b1[0]
            x = lfilter([b10, b00], [1.0, -a0], us, zi=[(1.0 - b10) * us[0]])[0]
            dx = lfilter([b10, b00], [1.0, -a0], dus, axis=0, zi=((1.0 - b10) * dus[:1]))[0]
            forcing = np.empty_like(us)
            forcing[0] = 0.0
            forcing[1:] = da[0] * x[:-1] + db0[0] * us[:-1] + db1[0] * us[1:]
            dtau = lfilter([1.0], [1.0, -a0], forcing)
        else:
            a_full = np.concatenate([[1.0], a])
            drive = np.zeros_like(us)
            drive[1:] = b0 * us[:-1] + b1 * us[1:]
            x = linear_recurrence(a_full, drive, us[0])
            ddrive = np.zeros_like(dus)
            ddrive[1:] = b0[:, None] * dus[:-1] + b1[:, None] * dus[1:]
            dx = linear_recurrence(a_full, ddrive, dus[0])
            forcing = np.zeros_like(us)
            forcing[1:] = da * x[:-1] + db0 * us[:-1] + db1 * us[1:]
            dtau = linear_recurrence(a_full, forcing, 0.0)
        x_out[s:e], dx_out[s:e], dtau_out[s:e] = x, dx, dtau
    return x_out, dx_out, dtau_out


def driven_alpha(data, drive: float) -> tuple[np.ndarray, np.ndarray]:
    """(alpha, alpha_dot) a state of ``drive`` reads (:class:`SeparationState`): the aircraft's, or a wing's own,
    alpha + drive p*, with its rate alpha_dot + drive dp*/dt (each maneuver differentiated on its own, as
    alpha_dot is). A wing's pair is kept in the data's memo: every model bound to the data reads the same one."""
    if not drive:
        return data["alpha"], data["alpha_dot"]
    memo = data.memo("driven alpha")
    if drive not in memo:
        pstar = data["p"] * data.constants["b"] / (2.0 * data["V"])
        t, periods = data["t"], data.period_array
        rate = np.concatenate([derivative(pstar[a:b], t[a:b], None if periods is None or not np.isfinite(periods[k])
                                          else float(periods[k]))
                               for k, (a, b) in enumerate(zip(data.bounds[:-1], data.bounds[1:]))])
        pair = (data["alpha"] + drive * pstar, data["alpha_dot"] + drive * rate)
        for x in pair:
            x.setflags(write=False)
        memo[drive] = pair
    return memo[drive]


def evaluate_state(state: SeparationState, values: dict[str, float], alpha: np.ndarray,
                   alpha_dot: np.ndarray, t: np.ndarray, bounds: np.ndarray,
                   step: float | None | bool = False, sensitivities: bool = True, periods=None):
    """Value of a separation state and its sensitivities.

    ``values`` maps base parameter names (``a1``, ``tau2``...) to numbers. Returns
    ``X`` (n,) and ``dX`` (n, k) with columns in ``state.base_parameters`` order;
    ``dX`` is None without ``sensitivities`` (a prediction needs X alone). ``periods``: each maneuver's period
    where it is periodic (NaN where not; :func:`first_order_lag`): an unsteady state starts there at its
    periodic solution.
    """
    return _evaluate_form(state, values, alpha, alpha_dot, t, bounds, step, sensitivities, periods)


def _evaluate_form(state: SeparationState, values: dict[str, float], alpha, alpha_dot, t, bounds, step,
                   sensitivities: bool, periods=None):
    """:func:`evaluate_state`: the static curve of the state's form (its record in :mod:`.static_forms`), the chain
    rule through alpha - tau2 alpha_dot (dX0/dtau2 = -dX0/dalpha alpha_dot), then the lag."""
    tau2 = values.get("tau2", 0.0)
    delayed, lagged = is_delayed(state.kind), is_lagged(state.kind)
    effective_alpha = alpha - tau2 * alpha_dot if delayed else alpha
    x0, dalpha, grads = static_gradient(state.form, effective_alpha, values, sensitivities)
    if not sensitivities:
        return _through_lags(state, values, t, x0, None, bounds, step, periods) if lagged else (x0, None)
    lead = 1 if delayed else 0
    du = np.empty((len(alpha), lead + grads.shape[1]), order="F")
    if lead:
        du[:, 0] = -dalpha * alpha_dot
    du[:, lead:] = grads
    if not lagged:
        return x0, du
    return _through_lags(state, values, t, x0, du, bounds, step, periods)


def _through_lags(state: SeparationState, values: dict[str, float], t, x0, du, bounds, step, periods):
    """A lagged state from its static value ``x0`` and that value's sensitivities ``du`` (None: the value alone):
    the lag by tau1 (its derivative first: U order tau1, tau2, the curve's; L tau1, the curve's), then for a
    vortex state the vortex's own lag (:func:`_vortex`)."""
    if du is None:
        x = first_order_lag(t, x0, None, values["tau1"], bounds, step, periods)[0]
        return (_vortex(t, x, None, values["tau_v"], bounds, step, periods)[0] if is_vortex(state.kind) else x), None
    x, dx, dtau1 = first_order_lag(t, x0, du, values["tau1"], bounds, step, periods)
    out = np.empty((len(x0), 1 + du.shape[1]), order="F")
    out[:, 0] = dtau1
    out[:, 1:] = dx
    if is_vortex(state.kind):
        return _vortex(t, x, out, values["tau_v"], bounds, step, periods)
    return x, out


def _vortex(t, xs, dxs, tau_v, bounds, step, periods):
    """V = Y - Xs with tau_v dY/dt + Y = Xs, from the lagged separation ``xs`` and its sensitivities ``dxs``
    (columns tau1, then the static curve's); returns V and dV in the V kind's order: tau1, tau_v, the curve's."""
    y, dy, dtau_v = first_order_lag(t, xs, dxs, tau_v, bounds, step, periods)
    if dxs is None:
        return y - xs, None
    out = np.empty((len(xs), dxs.shape[1] + 1), order="F")
    out[:, 0] = dy[:, 0] - dxs[:, 0]
    out[:, 1] = dtau_v
    out[:, 2:] = dy[:, 1:] - dxs[:, 1:]
    return y - xs, out
