"""The wheel model (paper 002 eq. 1-7), its Jacobian, its symmetries, and the sim://wheel rig."""

import numpy as np
import pytest

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError
from accelrig.procedures.wheel.model import (
    TABLE_I_OMEGA,
    FreeSet,
    WheelState,
    euler_from_rotation,
    model_and_jacobian,
    pack,
    predict,
    rotation_from_euler,
    unpack,
)
from accelrig.sim.rigs import RIGS
from accelrig.sim.rigs.wheel import WheelRig


def table_i_state(**changes) -> WheelState:
    values = dict(theta0=np.deg2rad(30), omega=TABLE_I_OMEGA, tilt=np.deg2rad(45), radius=0.28,
                  rotation=rotation_from_euler(np.deg2rad([30, 20, 25])), gain=[0.9, 1.0, 1.1], offset=[1, -1, 1])
    values.update(changes)
    return WheelState(**values)


@pytest.mark.parametrize("free", [FreeSet(radius_free=False, tilt_free=True), FreeSet(radius_free=True, tilt_free=False)])
def test_analytic_jacobian_matches_central_differences(free):
    t = np.arange(0, 60, 0.01)
    state = table_i_state()
    scale = 60.0
    _, jac = model_and_jacobian(t, state, free, scale)
    x = pack(state, free, scale)
    for k in range(x.size):
        h = 1e-6 * max(1.0, abs(x[k]))
        up, down = x.copy(), x.copy()
        up[k] += h
        down[k] -= h
        numeric = (predict(t, unpack(up, free, scale, state)) - predict(t, unpack(down, free, scale, state))) / (2 * h)
        assert np.allclose(jac[:, :, k], numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max()), free.names[k]


def test_model_is_eq_1_rotated_and_scaled():
    state = table_i_state()
    t = np.array([0.0, 1.0, 10.0])
    theta = state.theta0 + 9 * t - 0.045 * t**2 + 500e-6 / 3 * t**3 + 2e-6 / 4 * t**4
    rate = 9 - 0.09 * t + 500e-6 * t**2 + 2e-6 * t**3
    accel = -0.09 + 1e-3 * t + 6e-6 * t**2
    g = 9.80665
    a = np.column_stack([0.28 * rate**2 + g * np.sin(np.pi / 4) * np.cos(theta),
                         0.28 * accel + g * np.sin(np.pi / 4) * np.sin(theta),
                         np.full(3, g * np.cos(np.pi / 4))])
    expected = np.array([1, -1, 1]) + (a @ state.rotation.T) * np.array([0.9, 1.0, 1.1])
    assert np.allclose(predict(t, state), expected)


def test_canonical_folds_equivalent_solutions_without_changing_the_data():
    t = np.linspace(0, 30, 3000)
    base = table_i_state()
    # alpha -> -alpha with theta0 + pi; then a gain pair flipped with R flipped: the same data
    odd = table_i_state(tilt=-base.tilt, theta0=base.theta0 + np.pi,
                        gain=[-0.9, -1.0, 1.1], rotation=np.diag([-1.0, -1.0, 1.0]) @ base.rotation)
    assert np.allclose(predict(t, odd), predict(t, base))
    folded = odd.canonical()
    assert np.allclose(predict(t, folded), predict(t, base))
    assert np.allclose(folded.gain, base.gain)
    assert np.isclose(folded.tilt, base.tilt)
    assert np.allclose(folded.euler, base.euler)
    # tilt beyond 90 degrees: the spin direction flips instead
    over = table_i_state(tilt=np.pi - base.tilt, omega=-TABLE_I_OMEGA, theta0=-base.theta0,
                         rotation=base.rotation @ np.diag([1.0, -1.0, -1.0]))
    assert np.allclose(predict(t, over), predict(t, base))
    assert np.allclose(predict(t, over.canonical()), predict(t, base))
    assert over.canonical().tilt <= np.pi / 2


def test_euler_round_trip():
    angles = np.deg2rad([30, 20, 25])
    assert np.allclose(euler_from_rotation(rotation_from_euler(angles)), angles)


def test_rig_is_registered_and_its_independent_truth_agrees_with_eq_1():
    """The rig differentiates the rim's trajectory numerically (no eq. 1 inside): the model the
    estimator fits must agree with it to the stencil's rounding error (a few 1e-6 m/s^2 after
    100 turns), not merely to the noise."""
    assert RIGS["wheel"] is WheelRig
    rig = WheelRig.from_url(DeviceURL.parse("sim://wheel?speed=9&misalignment=30,20,25"), np.random.default_rng(0))
    t = np.linspace(0, 90, 5000)
    state = table_i_state(gain=[1, 1, 1], offset=[0, 0, 0])
    assert np.max(np.abs(rig.specific_force(t) - predict(t, state))) < 1e-5
    # what rides the rim always feels 1 g besides its own centripetal and tangential acceleration
    theta, rate = rig.motion(t)
    accel = np.polynomial.Polynomial(TABLE_I_OMEGA).deriv()(t)
    bench = rig.specific_force(t) @ rig.rotation
    motion = np.column_stack([0.28 * rate**2, 0.28 * accel, np.zeros_like(t)])
    assert np.allclose(np.linalg.norm(bench - motion, axis=1), 9.80665, atol=1e-5)


def test_coulomb_viscous_rig_obeys_its_friction_law_and_stops():
    rig = WheelRig(friction="coulomb-viscous", omega=[3.0, 0, 0, 0], coulomb=0.05, viscous=0.02)
    t = np.linspace(0, 120, 120001)
    theta, rate = rig.motion(t)
    moving = rate > 0.05
    accel = np.gradient(rate, t)
    assert np.allclose(accel[1:-1][moving[1:-1]], -(0.05 + 0.02 * rate[1:-1][moving[1:-1]]), atol=1e-6)
    assert np.allclose(np.gradient(theta, t)[1:-1][moving[1:-1]], rate[1:-1][moving[1:-1]], atol=1e-6)
    t_stop = np.log1p(3.0 / (0.05 / 0.02)) / 0.02
    assert np.all(rate[t > t_stop] == 0) and np.all(rate[t < t_stop - 0.1] > 0)
    assert np.ptp(theta[t > t_stop]) < 1e-12  # a stopped wheel stays put


@pytest.mark.parametrize("query, fragment", [
    ("friction=sticky", "friction"),
    ("omega=1,2", "4 comma-separated"),
    ("tilt_deg=120", "0 .. 90"),
    ("radius=-1", "radius"),
])
def test_rig_options_are_checked(query, fragment):
    with pytest.raises(DeviceError, match=fragment):
        WheelRig.from_url(DeviceURL.parse(f"sim://wheel?{query}"), np.random.default_rng(0))
