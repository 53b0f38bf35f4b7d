"""Data reduction equations (issue 15 item 5), each against an independent hand calculation."""
import numpy as np
import pytest

from structsearch.data.reduction import (body_force_coefficients, isa_density, lift_drag, pitch_moment_coefficient,
                                         specific_force_at_cg)
from structsearch.flight.raw import specific_force_at


def test_isa_density_matches_the_standard_atmosphere_table():
    # ICAO standard atmosphere table: pressure and temperature, density by the gas law rho = p / (R T)
    for h, p, temperature in ((0.0, 101_325.0, 288.15), (5000.0, 54_019.9, 255.65), (11_000.0, 22_632.1, 216.65)):
        assert isa_density(h) == pytest.approx(p / (287.053 * temperature), rel=2e-5), h


def test_accelerometer_to_cg_is_the_rigid_body_correction():
    rng = np.random.default_rng(3)
    for _ in range(5):
        ax, az, q, q_dot = rng.normal(size=4)
        r = rng.normal(size=3)
        omega, omega_dot = np.array([0.0, q, 0.0]), np.array([0.0, q_dot, 0.0])
        at_cg = np.array([ax, 0.0, az]) - np.cross(omega_dot, r) - np.cross(omega, np.cross(omega, r))
        assert specific_force_at_cg(ax, az, q, q_dot, r) == pytest.approx((at_cg[0], at_cg[2]), rel=1e-12)
        # and the simulator's accelerometer model is its inverse
        back = specific_force_at_cg(*specific_force_at(ax, az, q, q_dot, r), q, q_dot, r)
        assert back == pytest.approx((ax, az), rel=1e-12)


def test_body_force_coefficients_by_hand():
    # 5000 kg, 1 m/s^2 forward and -9 m/s^2 normal specific force, 10 kN thrust, q S = 50 kN
    cx, cz = body_force_coefficients(1.0, -9.0, 5000.0, 10_000.0, 50_000.0)
    assert cx == pytest.approx((5000.0 - 10_000.0) / 50_000.0) and cx == pytest.approx(-0.1)
    assert cz == pytest.approx(-0.9)


@pytest.mark.parametrize("alpha", [0.0, 0.1, 0.3, np.pi / 2])
def test_lift_and_drag_are_the_force_against_the_stability_axes(alpha):
    cx, cz = -0.05, -1.1
    x_s = np.array([np.cos(alpha), np.sin(alpha)])    # stability x axis in body (x, z)
    z_s = np.array([-np.sin(alpha), np.cos(alpha)])   # stability z axis in body (x, z)
    force = np.array([cx, cz])
    cl, cd = lift_drag(cx, cz, alpha)
    assert cd == pytest.approx(-force @ x_s, abs=1e-15) and cl == pytest.approx(-force @ z_s, abs=1e-15)


def test_pitch_moment_by_hand():
    # Iyy q_dot = 20; (Ixx - Izz) p r = (5 - 8) * 1 * 2 = -6; Ixz (p^2 - r^2) = 1 * (1 - 4) = -3;
    # thrust moment 100 N * 0.1 m = 10; q S cbar = 2 * 0.5 = 1
    cm = pitch_moment_coefficient(2.0, 10.0, 2.0, 0.5, thrust=100.0, thrust_line_z=0.1, p=1.0, r=2.0,
                                  ixx=5.0, izz=8.0, ixz=1.0)
    assert cm == pytest.approx(20.0 - 6.0 - 3.0 - 10.0)
    assert pitch_moment_coefficient(2.0, 10.0, 2.0, 0.5) == pytest.approx(20.0)
