"""Ringing or play at the dead centres (slider-crank `_is_link_ringing`): the decision on the steps' ring
frequencies, the harmonics' trend and how the event's size follows the speed.  The ring frequency is the one
`ring_frequency` would read; the steps are stand-ins carrying what the gate reads, so each rule is seen alone."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from accelrig.procedures.slider_crank import analysis

SPEEDS = (3.0, 4.5, 6.5, 8.5, 10.0)


def flagged_steps(knocks, ring_hz=450.0):
    return [SimpleNamespace(backlash=True, take_up_deg=0.0, knock_peak=k, ring=ring_hz,
                            frequency_hz=SimpleNamespace(value=f), state=SimpleNamespace(times=np.zeros(4)))
            for f, k in zip(SPEEDS, knocks, strict=True)]


@pytest.fixture
def rings_read_on(monkeypatch):
    """ring_frequency reads each stand-in's ring on a periodogram of the given bin (Hz)."""
    def use(bin_hz):
        monkeypatch.setattr(analysis, "ring_frequency", lambda s: (s.ring, 1.0, bin_hz))
    return use


def c_of(f_hz):
    return 1.0 / (2 * np.pi * f_hz) ** 2


def test_the_knock_growth_is_the_exponent_of_its_size_against_the_speed():
    assert analysis.knock_growth(flagged_steps([1.0] * 5)) == pytest.approx(0.0, abs=1e-12)
    assert analysis.knock_growth(flagged_steps([0.3 * f for f in SPEEDS])) == pytest.approx(1.0)
    assert analysis.knock_growth(flagged_steps([0.1 * f**2 for f in SPEEDS])) == pytest.approx(2.0)
    assert np.isnan(analysis.knock_growth(flagged_steps([1.0] * 5)[:1]))


def test_a_trend_that_cannot_rule_out_a_rigid_link_names_the_ring_only_if_it_keeps_its_size(rings_read_on):
    # a 450 Hz link's trend over 3-10 Hz: c 0.4 of the ring's, u 0.45 of it (measured 0.37-2.2 and 0.39-0.63):
    # it agrees with the ring, and with a rigid link as well
    rings_read_on(0.5)
    c_ring = c_of(450.0)
    c, u_c = 0.4 * c_ring, 0.45 * c_ring
    assert analysis._is_link_ringing(flagged_steps([0.7, 0.9, 1.0, 1.0, 1.0]), c, u_c)        # a friction step
    assert not analysis._is_link_ringing(flagged_steps([0.3 * f for f in SPEEDS]), c, u_c)   # an impact
    # a trend that rules out a rigid link decides alone, whatever the event's size does
    assert analysis._is_link_ringing(flagged_steps([0.3 * f for f in SPEEDS]), c_ring, 0.2 * c_ring)
    # and a trend that rules out this ring's compliance names play, however steady the event
    assert not analysis._is_link_ringing(flagged_steps([1.0] * 5), 0.0, 0.2 * c_ring)


def test_rings_that_all_peak_in_one_bin_are_known_to_that_bin_not_to_zero(rings_read_on):
    # all five steps ring at 450.0 Hz: a scatter of 0; a trend 0.5 % off the ring's compliance with u 0.1 % of it
    # agrees once the frequency's u is the bin (0.5 Hz: 0.22 % of c_ring), not 0
    c_ring = c_of(450.0)
    rings_read_on(0.5)
    assert analysis._is_link_ringing(flagged_steps([1.0] * 5), 1.005 * c_ring, 0.001 * c_ring)
    rings_read_on(0.0)
    assert not analysis._is_link_ringing(flagged_steps([1.0] * 5), 1.005 * c_ring, 0.001 * c_ring)


def test_rings_at_different_frequencies_are_play_whatever_the_trend(rings_read_on):
    rings_read_on(0.5)
    steps = flagged_steps([1.0] * 5)
    for s, f in zip(steps, (66.0, 90.0, 120.0, 150.0, 174.0), strict=True):
        s.ring = f
    assert not analysis._is_link_ringing(steps, c_of(120.0), 0.1 * c_of(120.0))
