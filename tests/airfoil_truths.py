"""Pitching-airfoil campaigns with a known lift truth simpler than the lift grid's structures, made without the
engine: the separation state is integrated by scipy's adaptive Runge-Kutta (not the engine's exact discretisation),
the campaign written as CSV files and campaign.toml by hand. The truths: a symmetric section (no C_L0), a lagged
state without the alpha_dot delay (tau2 = 0), a quasi-steady state (tau1 = 0), and no state at all (linear lift)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

CHORD, SPEED = 0.5, 30.0
RATE = 100.0                                   # samples per second
TRAIN_HZ, VALIDATION_HZ = (0.4, 0.7, 1.0, 1.3), (0.55, 1.15)


@dataclass(frozen=True)
class LiftTruth:
    """C_L = cl0 + cl_kl * ((1 + sqrt(X))/2)^2 * alpha; the state ``kind`` (U, L, Q or None) with its lag ``tau1``,
    delay ``tau2`` and tanh curve (a1, a_star); the pitching motion's mean and amplitude [rad]."""

    name: str
    cl0: float
    cl_kl: float
    kind: str | None
    tau1: float = 0.0
    tau2: float = 0.0
    a1: float = 20.0
    a_star: float = 0.30
    mean: float = 0.06            # -13.8 to 20.6 deg: through zero alpha, so that C_L0 and the lift slope separate
    amplitude: float = 0.30


TRUTHS = {
    "symmetric": LiftTruth("symmetric", 0.0, 5.8, "U", tau1=0.08, tau2=0.03),
    "lag_only": LiftTruth("lag_only", 0.12, 5.6, "L", tau1=0.10),
    "quasi_steady": LiftTruth("quasi_steady", 0.12, 5.6, "Q", tau2=0.05),
    "linear": LiftTruth("linear", 0.10, 5.5, None, mean=0.10, amplitude=0.09),
}


def _static(truth: LiftTruth, alpha_eff):
    return 0.5 * (1.0 - np.tanh(truth.a1 * (alpha_eff - truth.a_star)))


def _record(truth: LiftTruth, hz: float, cycles: int = 3):
    t = np.arange(0.0, cycles / hz, 1.0 / RATE)
    w = 2 * np.pi * hz

    def alpha(s):
        return truth.mean - truth.amplitude * np.cos(w * s)

    def alpha_dot(s):
        return truth.amplitude * w * np.sin(w * s)

    if truth.kind is None:
        x = np.ones_like(t)
    elif truth.kind == "Q":
        x = _static(truth, alpha(t) - truth.tau2 * alpha_dot(t))
    else:
        def rhs(s, y):
            return [(_static(truth, alpha(s) - truth.tau2 * alpha_dot(s)) - y[0]) / truth.tau1]
        x0 = _static(truth, alpha(0.0) - truth.tau2 * alpha_dot(0.0))
        x = solve_ivp(rhs, (t[0], t[-1]), [x0], t_eval=t, rtol=1e-10, atol=1e-12, max_step=0.01).y[0]
    cl = truth.cl0 + truth.cl_kl * ((1 + np.sqrt(x)) / 2) ** 2 * alpha(t)
    return t, alpha(t), alpha_dot(t), cl


def write_campaign(truth: LiftTruth, directory: Path, seed: int, noise: float = 0.02) -> Path:
    """The campaign of ``truth`` in ``directory``: four training runs and two validation runs of three cycles
    each, C_L with white noise of ``noise`` (seeded)."""
    rng = np.random.default_rng(seed)
    directory.mkdir(parents=True, exist_ok=True)
    entries = []
    for split, freqs in (("train", TRAIN_HZ), ("validation", VALIDATION_HZ)):
        for hz in freqs:
            t, alpha, q, cl = _record(truth, hz)
            cl = cl + rng.normal(0.0, noise, len(t))
            cd = 0.01 + 0.8 * alpha ** 2 + rng.normal(0.0, 0.002, len(t))
            cm = -0.02 - 0.1 * alpha + rng.normal(0.0, 0.002, len(t))
            mid = f"{split}_{hz:.2f}hz".replace(".", "p")
            rows = ["t,alpha,q,V,de,CL,CD,Cm"] + [
                f"{t[i]:.4f},{alpha[i]:.9g},{q[i]:.9g},{SPEED},0,{cl[i]:.9g},{cd[i]:.9g},{cm[i]:.9g}"
                for i in range(len(t))]
            (directory / f"{mid}.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
            entries.append(f'[[maneuver]]\nid = "{mid}"\nfile = "{mid}.csv"\nkind = "deep-dynamic"\n'
                           f'split = "{split}"\n')
    (directory / "campaign.toml").write_text(
        f'name = "pitching section, truth {truth.name}, seed {seed}"\n\n[aircraft]\nS = {CHORD}\ncbar = {CHORD}\n'
        "b = 1.0\n\n" + "\n".join(entries), encoding="utf-8")
    return directory
