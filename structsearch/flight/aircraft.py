"""Aircraft the simulator can fly: geometry, mass, pitch inertia, engines; the ISA atmosphere (SI units).

An :class:`Aircraft` is plain data. The Citation II (PH-LAB) numbers come from the thesis and
docs/catalogue.md (section 6); the twin-jet transport of :mod:`structsearch.flight.transport` is ours. A
campaign of another aircraft carries its own data in campaign.toml (docs/interfaces.md 5.1), from which
:func:`aircraft_of_campaign` builds what the forward simulation needs.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..data.errors import DataError, DeclarationError
from ..data.reduction import G, RHO0, isa_density, isa_speed_of_sound  # noqa: F401  (G: the simulator reads ac.G)
from .reference import AIRCRAFT, EMPTY_MASS, IYY

FT = 0.3048
INCH = 0.0254
density = isa_density
speed_of_sound = isa_speed_of_sound


def flight_level_altitude(fl: float) -> float:
    return fl * 100 * FT


@dataclass(frozen=True)
class Aircraft:
    """What the simulator needs to know about an aircraft besides its aerodynamics."""

    name: str
    label: str
    S: float                      # wing area [m^2]
    cbar: float                   # mean aerodynamic chord [m]
    b: float                      # span [m]
    empty_mass: float             # [kg], with the test equipment
    crew_mass: float              # [kg]
    iyy_empty: float              # pitch inertia at the empty mass [kg m^2]
    iyy_per_kg: float             # [m^2]: what a kilogram of fuel or crew adds (carried near the cg)
    max_thrust_sl: float          # all engines, static, sea level [N]
    max_fuel_flow: float          # all engines at full throttle [kg/s]; scales with throttle
    x_cg_range: tuple[float, float] | None = None  # cg envelope [m], the datum of the x_cg column
    records_cg: bool = True       # the campaign files carry an x_cg column
    # The fixed station [m] a pitch model may take C_m about (docs/interfaces.md 7.5), the x_cg column's datum
    reference_point: float | None = None
    # Pitch-rate gyro: white noise [rad/s] left after flight-path reconstruction, and the rate vibration
    # [rad/s per unit of buffet] it sees in separated flow. C_m comes from q_dot * Iyy / (qbar S cbar), so
    # what matters is their size in moment-coefficient terms; a heavy aircraft needs quieter rates.
    gyro_noise: float = 0.0015
    gyro_buffet: float = 0.004

    def inertia(self, mass):
        """Pitch inertia [kg m^2] at ``mass``."""
        return self.iyy_empty + self.iyy_per_kg * (np.asarray(mass) - self.empty_mass)

    def max_thrust(self, h, rho=None):
        """Available thrust [N] of all engines at altitude (density lapse^0.75); ``rho``: density(h), when
        the caller has it."""
        return self.max_thrust_sl * ((density(h) if rho is None else rho) / RHO0) ** 0.75

    def manifest(self, mass: float) -> dict:
        """The [aircraft] table of campaign.toml (docs/interfaces.md 5.1) for a campaign flown at about ``mass``:
        one pitch inertia, as a flight-test engineer states it for the test weight."""
        out = {"S": self.S, "cbar": self.cbar, "b": self.b, "Iyy": round(float(self.inertia(mass)), 1)}
        if self.x_cg_range is not None:
            out["x_cg_range"] = tuple(self.x_cg_range)
        if self.reference_point is not None:
            out["reference_point"] = self.reference_point
        return out


# Two Pratt & Whitney JT15D-4, about 11.1 kN static sea-level thrust each; 0.16 kg/s of fuel at full
# throttle; cg envelope 276-286 in from the datum 15 in ahead of the nose (docs/catalogue.md section 6). The
# moment reference point is the middle of the band the test flights were loaded in (280.5-282 in,
# .flighttest.FLOWN_CG_RANGE): the thesis' identified C_m terms hold about the cg there.
CITATION_REFERENCE_POINT = 281.25 * INCH
CITATION = Aircraft(
    name="citation", label="Citation II", S=AIRCRAFT["S"], cbar=AIRCRAFT["cbar"], b=AIRCRAFT["b"],
    empty_mass=EMPTY_MASS, crew_mass=3 * 85.0, iyy_empty=IYY, iyy_per_kg=0.9,
    max_thrust_sl=2 * 11_100.0, max_fuel_flow=0.16, x_cg_range=(276 * INCH, 286 * INCH),
    reference_point=CITATION_REFERENCE_POINT)


def cg_band(spread: float, aircraft: Aircraft, flown: tuple[float, float] | None) -> tuple[float, float]:
    """The band [m] each loading's cg is drawn from (``simulate --cg-spread``): ``spread`` wide around the middle
    of the ``flown`` band (the Citation's reference point), inside the aircraft's cg envelope."""
    envelope = aircraft.x_cg_range
    if envelope is None or flown is None:
        raise DeclarationError(f"cg spread: the {aircraft.label} flies one fixed cg, not recorded")
    centre = 0.5 * (flown[0] + flown[1])
    widest = 2 * min(centre - envelope[0], envelope[1] - centre)
    if not (isinstance(spread, (int, float)) and np.isfinite(spread) and 0 < spread <= widest):
        raise DeclarationError(f"cg spread {spread!r} m: the width of the band the loadings' cg is drawn from, "
                               f"above 0 and at most {widest:.4f} m (the cg envelope around {centre:.4f} m); "
                               f"the default band is {flown[1] - flown[0]:.4f} m wide")
    return centre - 0.5 * spread, centre + 0.5 * spread


def aircraft_of_campaign(constants: Mapping[str, float], source: str = "") -> Aircraft:
    """The aircraft of a campaign for the forward simulation: S and cbar from [aircraft], the pitch
    inertia ``Iyy`` (docs/interfaces.md 5.1) constant over the campaign. Engines and mass come from the data
    (CT and the mass column), so they are not needed here."""
    missing = [k for k in ("S", "cbar", "Iyy") if k not in constants]
    if missing:
        raise DataError(f"forward simulation needs [aircraft] {missing[0]} in campaign.toml "
                        "(the pitch inertia turns C_m into pitch acceleration)", source=source or None)
    return Aircraft(name="campaign", label="campaign aircraft", S=float(constants["S"]),
                    cbar=float(constants["cbar"]), b=float(constants.get("b", np.nan)), empty_mass=0.0,
                    crew_mass=0.0, iyy_empty=float(constants["Iyy"]), iyy_per_kg=0.0,
                    max_thrust_sl=np.nan, max_fuel_flow=0.0)
