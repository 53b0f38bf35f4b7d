"""Reference values of the thesis (docs/catalogue.md section 6): the simulator's truth.

Only the identified Citation II numbers live here; candidate grids are declared
in ``model_specs/``.
"""
from __future__ import annotations

from ..engine.stallmodel import StallModel

# The final models of the thesis, by coefficient: the one place these names are written.
# Their structures are declared below for the simulator's truth; tests/test_architecture.py
# checks them equal to the candidates of the same names in model_specs/.
FINAL_MODEL_NAMES = {"CL": "CL-VI", "CD": "CD-IXr", "Cm": "Cm-XXXIIIr"}
VAN_INGEN_MODEL_NAMES = {"CL": "CL-I", "CD": "CD-I", "Cm": "Cm-I"}

AIRCRAFT = {"S": 30.0, "cbar": 2.013, "b": 15.75}
EMPTY_MASS = 4161.3   # kg
IYY = 31501.0         # kg m^2

FINAL_LIFT = {
    "tau1_ss": 0.4191, "tau2_ss": 0.3391, "a1_ss": 70.2846, "a_star_ss": 0.1956,
    "a1_w": 13.9276, "a_star_w": 0.3267,
    "CL0": 0.2318, "CL_KL_ss": 1.3851, "CL_KL_w": 2.5961, "CL_qstar": 8.0747, "CL_de": -0.3403,
}

FINAL_DRAG = {
    "CD0": 0.0165, "CD_CT": 0.3917, "CD_de": -0.1894, "CD_CL2": 0.0258,
    "CD_1mX_ss": 0.0555, "CD_1mX_w": 0.2062,
}

FINAL_PITCH = {
    "Cm0": 0.0659, "Cm_CT": 0.0794, "Cm_qstar": -1.7502, "Cm_de": -0.7431,
    "Cm_xcgCL": -0.9616, "Cm_CL": 3.2316, "Cm_1mX_ssCL": -0.0517, "Cm_1mX_wCL": -0.0681,
    "Cm_Xde_ss": -0.2576,
}

# Standard deviations the thesis reports for its final models on the real flight data (Tables 11, 13,
# 15 of the seed): the target of the simulator's error levels (README, `results/thesis_stderr.md`).
THESIS_STDERR = {
    "tau1_ss": 0.0722, "tau2_ss": 0.0346, "a1_ss": 11.2205, "a_star_ss": 0.0017, "a1_w": 1.4462,
    "a_star_w": 0.0056, "CL0": 0.0116, "CL_KL_ss": 0.1061, "CL_KL_w": 0.0536, "CL_qstar": 1.3881,
    "CL_de": 0.0681,
    "CD0": 0.0020, "CD_CT": 0.0135, "CD_de": 0.0131, "CD_CL2": 0.0035, "CD_1mX_ss": 0.0017, "CD_1mX_w": 0.0064,
    "Cm0": 0.0026, "Cm_CT": 0.0089, "Cm_qstar": 0.2675, "Cm_de": 0.0134, "Cm_xcgCL": 0.1305, "Cm_CL": 0.4594,
    "Cm_1mX_ssCL": 0.0033, "Cm_1mX_wCL": 0.0053, "Cm_Xde_ss": 0.0224,
}

VAN_INGEN_LIFT = {
    "tau1": 0.2547, "tau2": 0.0176, "a1": 27.6711, "a_star": 0.2084,
    "CL0": 0.1758, "CL_KL": 4.6605, "CL_spline": 10.7753,
}


def final_lift_model() -> StallModel:
    """CL-VI: X_ss unsteady, X_w steady; K_L(X_ss), K_L(X_w), q*, delta_e and C_L0."""
    return StallModel.declare(
        FINAL_MODEL_NAMES["CL"], "CL", states={"ss": "U", "w": "S"},
        regressors={"CL0": "1", "CL_KL_ss": "K_L(X_ss)", "CL_KL_w": "K_L(X_w)",
                    "CL_qstar": "qstar", "CL_de": "de"})


def van_ingen_lift_model() -> StallModel:
    """CL-I: one unsteady state X; K_L(X), the (alpha - 6 deg)+^2 spline and C_L0."""
    return StallModel.declare(
        VAN_INGEN_MODEL_NAMES["CL"], "CL", states={"": "U"},
        regressors={"CL0": "1", "CL_KL": "K_L(X)", "CL_spline": "spline"})


def _separation_of(lift_params) -> dict[str, float]:
    keys = ("tau1_ss", "tau2_ss", "a1_ss", "a_star_ss", "a1_w", "a_star_w")
    return {k: lift_params[k] for k in keys if k in lift_params}


def final_drag_model(lift_params=FINAL_LIFT) -> StallModel:
    """CD-IXr (Eq. 35): C_D0, C_T, delta_e, C_L^2, (1-X_ss), (1-X_w); states from the lift model."""
    return StallModel.declare(
        FINAL_MODEL_NAMES["CD"], "CD", states={"ss": "U", "w": "S"}, fixed=_separation_of(lift_params),
        regressors={"CD0": "1", "CD_CT": "CT", "CD_de": "de", "CD_CL2": "CL**2",
                    "CD_1mX_ss": "1 - X_ss", "CD_1mX_w": "1 - X_w"})


def final_pitch_model(lift_params=FINAL_LIFT) -> StallModel:
    """Cm-XXXIIIr (Eq. 30): Cm-XXXIII without X_w*delta_e; states from the lift model."""
    return StallModel.declare(
        FINAL_MODEL_NAMES["Cm"], "Cm", states={"ss": "U", "w": "S"}, fixed=_separation_of(lift_params),
        regressors={"Cm0": "1", "Cm_CT": "CT", "Cm_qstar": "qstar", "Cm_de": "de",
                    "Cm_xcgCL": "x_cg/cbar*CL", "Cm_CL": "CL", "Cm_1mX_ssCL": "(1 - X_ss)*CL",
                    "Cm_1mX_wCL": "(1 - X_w)*CL", "Cm_Xde_ss": "X_ss*de"})
