"""The wheel's residual checks and survey read the record chunk by chunk (issue 18: memory O(p^2) beyond
the data); chunking must not change a number, and the checks' tests must hold their stated level."""

import numpy as np
import pytest
from scipy import stats

from accelrig.procedures.wheel import checks
from accelrig.procedures.wheel.assumptions import check_residuals
from accelrig.procedures.wheel.fit import free_set
from accelrig.procedures.wheel.model import TABLE_I_OMEGA, WheelState, predict, rotation_from_euler
from accelrig.sim.device import simulate
from accelrig.sim.rigs.wheel import WheelRig
from accelrig.sim.sensor import SensorModel, SimClock


def test_the_survey_is_the_same_in_chunks_as_in_one_piece(monkeypatch):
    rig = WheelRig(radius=0.28, duration=12.0, omega=TABLE_I_OMEGA * 6.0 / 9.0)
    sensor = SensorModel(offset=(0.3, -0.2, 0.25), gain=(0.98, 1.0, 1.02), range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(0.08, 200.0))
    rec = simulate(rig, sensor, SimClock(200.0), seconds=12.0, seed=1)
    t, v = rec.t - rec.t[0], rec.to_si().acc
    whole = checks.survey(t, v)
    # chunks shorter than the moving average's reach, an odd size, so no boundary falls on a round number
    monkeypatch.setattr(checks, "SURVEY_CHUNK", 97)
    parts = checks.survey(t, v)
    lean = checks.survey(t, v, keep_angle=False)
    assert np.allclose(parts.angle, whole.angle, rtol=0, atol=1e-9)
    for name in ("turns", "gravity_amplitude", "speed_start", "speed_end", "noise_sd"):
        assert getattr(parts, name) == pytest.approx(getattr(whole, name), rel=1e-9)
        assert getattr(lean, name) == getattr(parts, name)
    assert lean.angle is None
    # the noise is read from every k-th instant on a long record: still the same sd to a few percent
    monkeypatch.setattr(checks, "NOISE_INSTANTS", 500)
    assert checks.noise_sd(v) == pytest.approx(whole.noise_sd, rel=0.1)
    assert whole.noise_sd == pytest.approx(0.08, rel=0.1)


def _state() -> WheelState:
    return WheelState(0.5, TABLE_I_OMEGA * 6.0 / 9.0, np.deg2rad(45.0), 0.28,
                      rotation_from_euler(np.deg2rad([30.0, 20.0, 25.0])), (0.98, 1.0, 1.02), (0.3, -0.2, 0.25))


@pytest.mark.parametrize("rho", [0.0, 0.9])
def test_the_score_tests_hold_their_level_on_noise_around_a_true_model(rho):
    # Noise around the true model: the speed-law and drift tests' p-values are uniform (white: chi-square;
    # correlated: batch means with Hotelling's correction), so each fires in ALPHA of clean recordings.
    rng = np.random.default_rng(20 + int(10 * rho))
    n, runs = (4000, 150) if rho == 0 else (16000, 60)
    t = np.arange(n) / 200.0
    state = _state()
    clean = predict(t, state)
    free = free_set(0.28, None)
    noise_model = SensorModel(noise_density=SensorModel.noise_density_for_sd(0.08, 200.0), ar1=rho, range_g=16)
    p_values = []
    for _ in range(runs):
        noise_model._noise_state = None
        noise = noise_model.noise(n, rng, 200.0)
        found = check_residuals(t, clean + noise, state, free, float(t[-1]), np.full(3, 1 / 0.08), noise.copy())
        assert found.correlated or rho == 0
        p_values += [found.speed_law.p_value, found.drift.p_value]
    p_values = np.array(p_values)
    assert stats.kstest(p_values, "uniform").pvalue > 1e-3
    # 1 % level: at most the upper end of the binomial 99.9 % band
    assert np.mean(p_values < 0.01) <= stats.binom.ppf(0.999, p_values.size, 0.01) / p_values.size
