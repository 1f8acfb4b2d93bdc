"""Rate planning, the streaming anti-alias resampler, and counter-to-host-clock regression."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from accelrig.acquisition.chips.base import OFFSET_STEP, offset_value, offset_word, plan_offsets, plan_rate
from accelrig.acquisition.chips.decimate import RationalResampler
from accelrig.acquisition.chips.icm20948 import SPEC as ICM
from accelrig.acquisition.chips.mpu9250 import SPEC as MPU
from accelrig.acquisition.chips.timing import CounterClockFit
from accelrig.errors import DeviceError


@pytest.mark.parametrize("spec, requested, bypass, chip_rate, ratio, delivered", [
    (MPU, 2048, True, 4000, (64, 125), 2048),
    (MPU, 2000, True, 4000, (1, 2), 2000),
    (MPU, 1000, False, 1000, (1, 1), 1000),
    (MPU, 500, False, 500, (1, 1), 500),
    (MPU, 300, False, 1000 / 3, (1, 1), 1000 / 3),     # nearest DLPF rate, reported as such
    (MPU, 8000, True, 4000, (1, 1), 4000),
    (ICM, 2048, True, 4500, (512, 1125), 2048),
    (ICM, 1125, False, 1125, (1, 1), 1125),
    (ICM, 100, False, 1125 / 11, (1, 1), 1125 / 11),
])
def test_rate_plan_reports_the_rate_delivered(spec, requested, bypass, chip_rate, ratio, delivered):
    plan = plan_rate(spec, requested)
    assert plan.bypass == bypass
    assert plan.chip_rate == pytest.approx(chip_rate)
    assert (plan.up, plan.down) == ratio
    assert plan.delivered_rate == pytest.approx(delivered)


def test_rate_plan_refuses_nonsense():
    with pytest.raises(DeviceError):
        plan_rate(MPU, 0)


@pytest.mark.parametrize("fin, up, down", [(4000, 64, 125), (4500, 512, 1125), (4000, 1, 2)])
def test_resampler_passes_the_band_and_stops_aliases(fin, up, down):
    rs = RationalResampler(up, down)
    n = int(fin * 1.5)
    t = np.arange(n) / fin
    fout = fin * up / down
    alias = (fout / 2 + fin / 2) / 2      # between the output and the input Nyquist frequency
    x = np.stack([np.sin(2 * np.pi * 37 * t), np.sin(2 * np.pi * alias * t), np.ones(n)], axis=1)
    y, pos = rs.process(x)
    assert np.allclose(np.diff(pos), down / up)
    assert np.max(np.abs(y[:, 0] - np.sin(2 * np.pi * 37 * pos / fin))) < 1e-3
    assert np.max(np.abs(y[:, 1])) < 1e-3                      # at least 60 dB down
    assert np.allclose(y[:, 2], 1.0, atol=1e-4)                 # unity DC gain


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(1, 97), min_size=5, max_size=60))
def test_resampler_output_does_not_depend_on_how_the_stream_is_cut(cuts):
    rng = np.random.default_rng(1)
    x = rng.standard_normal((sum(cuts), 3))
    whole, whole_pos = RationalResampler(64, 125).process(x)
    rs = RationalResampler(64, 125)
    parts, pos, i = [], [], 0
    for c in cuts:
        y, p = rs.process(x[i:i + c])
        parts.append(y)
        pos.append(p)
        i += c
    np.testing.assert_allclose(np.concatenate(parts), whole, atol=1e-12)
    np.testing.assert_array_equal(np.concatenate(pos), whole_pos)


def test_counter_fit_estimates_rate_and_uncertainty_honestly():
    true_rate, t0 = 2056.7, 12.5
    zs = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        fit = CounterClockFit(2048.0)
        host = t0 + np.cumsum(0.01 + rng.uniform(0, 0.002, 500))   # polls, late by jitter
        produced = np.floor((host - t0) * true_rate)                 # samples in the FIFO then
        for k, h in zip(produced, host, strict=True):
            fit.add(k, h)
        zs.append((fit.rate - true_rate) / fit.rate_uncertainty)
        # Sample p was taken at t0 + (p + 1) / rate (first tick one period after start).
        p = np.array([100.0, 5000.0])
        assert np.max(np.abs(fit.times(p) - (t0 + (p + 1) / true_rate))) < 0.5 / true_rate
    assert abs(np.mean(zs)) < 1.5 and 0.3 < np.std(zs) < 2.0


def test_counter_fit_segments_share_the_slope_and_get_their_own_intercept():
    rate = 1000.0
    fit = CounterClockFit(990.0)
    for k in range(1, 200):
        fit.add(k * 10, k * 10 / rate)
    fit.new_segment()
    start = 3.0                                     # after a gap of unknown size
    fit.add(10, start + 10 / rate)                  # one poll is enough: slope is pooled
    assert fit.rate == pytest.approx(rate)
    assert fit.times(np.array([0.0]))[0] == pytest.approx(start + 0.5 / rate)


def test_offset_words_keep_the_reserved_bit_and_refuse_overflow():
    word = offset_word(-1234, 1)
    assert offset_value(word) == -1234 and word & 1
    with pytest.raises(DeviceError, match="15-bit"):
        offset_word(1 << 14, 0)
    plan = plan_offsets([offset_word(100, 1), offset_word(-50, 0), offset_word(0, 1)], [0.5, -0.25, 0.0])
    assert [w & 1 for w in plan.new_words] == [1, 0, 1]
    assert plan.steps == [round(0.5 / OFFSET_STEP), round(-0.25 / OFFSET_STEP), 0]
    assert np.all(np.abs(plan.residual) <= OFFSET_STEP / 2)
