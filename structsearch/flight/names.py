"""Names the simulator accepts (aircraft, withholdable effects, anomalies), importable without numpy or sympy.

The command line builds its choices from these (``structsearch --help`` stays fast); :mod:`.aero` and
:mod:`.anomalies` define the objects behind the names, and a test checks that both agree.
"""
from __future__ import annotations

# The aircraft the simulator flies (keys of :data:`structsearch.flight.aero.TRUTHS`).
AIRCRAFT_NAMES = ("citation", "transport")

# Effects of docs/interfaces.md section 3 that the final model contains, and what withholding does.
WITHHOLDABLE = {
    "unsteady_lag": "X_ss without its lag: tau1_ss = 0 (U -> Q)",
    "separation_delay": "X_ss without its delay: tau2_ss = 0",
    "second_separation_state": "no X_w: the outboard wing never separates (X_w = 1)",
    "pitch_rate": "no q* term in C_L (pitch damping Cm_q stays: the aircraft must stay flyable)",
    "elevator": "no delta_e term in C_L and C_D (elevator control power Cm_de stays)",
    "elevator_effectiveness_loss": "no X_ss*delta_e term in C_m",
    "thrust": "no C_T terms in C_D and C_m",
    "induced_drag": "no C_L^2 term in C_D",
    "separation_drag": "no (1-X) terms in C_D",
    "cp_shift": "no (1-X)*C_L terms in C_m",
}

# Effects outside the diagnosis' library (keys of :data:`structsearch.flight.anomalies.ANOMALIES`, in order).
ANOMALY_NAMES = ("reattachment_delay", "vane_lag", "compressibility", "reynolds_stall", "tail_aeroelastic",
                 "two_break_stall")
