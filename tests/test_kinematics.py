"""accelrig.sim.kinematics: specific force from a trajectory, against closed forms known here only."""

import numpy as np
import pytest

from accelrig.geometry import rot_z
from accelrig.sim import kinematics
from accelrig.units import STANDARD_GRAVITY as G

T = np.linspace(0.0, 100.0, 1001)


def upright(t):
    return np.broadcast_to(np.eye(3), (np.size(t), 3, 3))


def test_at_rest_the_axis_pointing_up_reads_plus_g():
    for up in np.eye(3):
        mounting = kinematics.level_mounting(np.roll(up, 1), up)
        force = kinematics.specific_force(kinematics.at_origin, lambda t, mounting=mounting: np.broadcast_to(mounting, (t.size, 3, 3)), T)
        assert np.array_equal(force, np.broadcast_to(G * up, force.shape))


def test_free_fall_reads_zero():
    def falling(t):  # thrown sideways from 2 m
        return np.column_stack([3.0 * t, -t, 2.0 - G * t**2 / 2])

    t = np.linspace(0.0, 0.6, 101)
    # rounding only: (16/3) eps |p| / h^2 with |p| < 2.5 m
    assert np.max(np.abs(kinematics.specific_force(falling, upright, t))) < 16 / 3 * 2.5 * 2.3e-16 / kinematics.DEFAULT_STEP**2


def test_a_polynomial_of_degree_five_is_exact_to_rounding():
    coefficients = np.array([[0.1, -0.2, 0.3, 0.05, -0.01, 0.002]] * 3) * [[1], [-2], [0.5]]

    def position(t):
        return np.column_stack([np.polynomial.polynomial.polyval(t, c) for c in coefficients])

    t = np.linspace(-2.0, 2.0, 101)
    exact = np.column_stack([np.polynomial.polynomial.polyval(t, np.polynomial.polynomial.polyder(c, 2))
                             for c in coefficients])
    # rounding: (16/3) eps |p| / h^2 with |p| < 1 m
    assert np.max(np.abs(kinematics.acceleration(position, t) - exact)) < 16 / 3 * 4e-16 / kinematics.DEFAULT_STEP**2


def test_uniform_circular_motion_reads_omega_squared_r_towards_the_centre():
    r, w = 0.28, 9.0

    def rim(t):
        return r * np.column_stack([np.cos(w * t), np.sin(w * t), np.zeros_like(t)])

    def turning(t):  # x radial outwards, y along the motion, z up
        return np.stack([rot_z(w * ti) for ti in t])

    force = kinematics.specific_force(rim, turning, T)
    assert np.allclose(force, [-w**2 * r, 0.0, G], rtol=0, atol=1e-6)


def test_error_stays_inside_the_documented_truncation_bound():
    """A fast sine: the stencil's error h^4/90 |p^(6)| dominates rounding, and is that large."""
    w, a = 2 * np.pi * 80.0, 1e-3

    def shaking(t):
        return np.column_stack([a * np.sin(w * t), np.zeros_like(t), np.zeros_like(t)])

    t = np.linspace(0.0, 1.0, 4001)
    error = np.max(np.abs(kinematics.acceleration(shaking, t)[:, 0] + a * w**2 * np.sin(w * t)))
    bound = kinematics.DEFAULT_STEP**4 / 90 * a * w**6
    assert bound / 3 < error <= bound * 1.01


@pytest.mark.parametrize("step", [2.0**-10, 2.0**-15])
def test_rounding_follows_the_accumulated_angle_over_the_step_squared(step):
    """After 900 rad the angle carries an ulp of 1.1e-13 rad: the rim point is off by r ulp / 2, which
    the stencil amplifies by (16/3) / h^2."""
    def rim(t):
        return 0.28 * np.column_stack([np.cos(9.0 * t), np.sin(9.0 * t), np.zeros_like(t)])

    error = np.abs(np.linalg.norm(kinematics.acceleration(rim, T, step), axis=1) - 0.28 * 81)
    rounding = 16 / 3 * 0.28 * np.spacing(900.0) / 2 / step**2
    truncation = step**4 / 90 * 0.28 * 9.0**6
    assert np.max(error) < rounding + truncation
