"""Ringing or play at the dead centres (slider-crank `_is_link_ringing`): the decision on the steps' ring
frequencies, the harmonics' trend and how the event's size follows the speed.  The ring frequency is the one
`ring_frequency` would read; the steps are stand-ins carrying what the gate reads, so each rule is seen alone."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from accelrig.procedures.slider_crank import analysis

SPEEDS = (3.0, 4.5, 6.5, 8.5, 10.0)


RADIUS, ROD = 0.008, 0.042


def flagged_steps(knocks, ring_hz=450.0, delay_rad=0.0, lost_m=10e-6, u_a3=0.002, harmonics=4):
    """Stand-ins flagged at the dead centres; ``delay_rad``: the crank angle after them at which the event starts
    (play crossed by the pin: sqrt(2 play / r); a link's friction ring: 0); ``lost_m``: the motion lost at each dead
    centre, which their third harmonic shows (A_3 = 9 omega^2 2 b / (3 pi)), with u ``u_a3`` (m/s^2).  The default
    10 um is play-sized, so the lost-motion rule stays out of the way of the others."""
    out = []
    for f, k in zip(SPEEDS, knocks, strict=True):
        omega2 = (2 * np.pi * f) ** 2
        amplitudes = [RADIUS * omega2, RADIUS**2 / ROD * omega2, 9 * omega2 * 2 * lost_m / (3 * np.pi), 0.01]
        out.append(SimpleNamespace(
            backlash=True, take_up_deg=0.0, knock_peak=k, ring=ring_hz, delay=delay_rad,
            frequency_hz=SimpleNamespace(value=f),
            harmonic_amplitudes=SimpleNamespace(value=amplitudes[:harmonics], uncertainty=[u_a3] * harmonics),
            state=SimpleNamespace(times=np.zeros(4), crank_radius=RADIUS, rod_length=ROD)))
    return out


def phase_of(step, f_ring):
    """What ring_phase reads on a stand-in: a ring starting ``delay`` rad of crank after the dead centre, i.e.
    delay / (2 pi f) s, has its phase at f_ring moved by 2 pi f_ring times that (plus a common 2.9 rad); u 2 deg."""
    return 2.9 - f_ring * step.delay / step.frequency_hz.value, np.radians(2.0), -0.04


@pytest.fixture
def rings_read_on(monkeypatch):
    """ring_frequency reads each stand-in's ring on a periodogram of the given bin (Hz); ring_phase its timing."""
    def use(bin_hz):
        monkeypatch.setattr(analysis, "ring_frequency", lambda s: (s.ring, 1.0, bin_hz))
        monkeypatch.setattr(analysis, "ring_phase", phase_of, raising=False)   # raising: main had none
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
    # an impact after the pin crossed 10 um of play (sqrt(2 x 10 um / 8 mm) = 0.05 rad)
    assert not analysis._is_link_ringing(flagged_steps([0.3 * f for f in SPEEDS], delay_rad=0.05), c, u_c)
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


def test_a_ring_that_grows_with_speed_is_the_link_only_if_it_keeps_its_timing_at_the_dead_centres(rings_read_on):
    """A rail whose friction turns over a broad band of speed rings the link more at the faster steps (g 1.3-1.5 on the
    held-out 450 Hz link, friction turning over 10 mm/s), but its force reverses about the moment the velocity does:
    one phase against the dead centres at every speed.  Play's knock comes a fixed crank angle after them, later in
    time at a slower step: its phase at the ring frequency moves.  On main the growth alone named it play."""
    rings_read_on(0.5)
    c_ring = c_of(450.0)
    c, u_c = 0.4 * c_ring, 0.45 * c_ring
    growing = [0.02 * f**1.5 for f in SPEEDS]
    assert analysis.knock_growth(flagged_steps(growing)) == pytest.approx(1.5)
    assert analysis._is_link_ringing(flagged_steps(growing), c, u_c)
    # 1 um of play (0.016 rad): the knock's phase moves by 450 x 0.016 x (1/3 - 1/10) = 1.7 rad over the steps
    assert not analysis._is_link_ringing(flagged_steps(growing, delay_rad=0.016), c, u_c)
    # one step cannot show a timing that holds
    assert not analysis._is_link_ringing(flagged_steps(growing)[:1], c, u_c)


def test_the_ring_timing_test_takes_the_ring_frequencys_u_and_wraps_the_phase(monkeypatch):
    steps = flagged_steps([1.0] * 5)
    phases = iter(np.radians([179.0, -179.0, 178.0, -178.0, 180.0]))     # one phase across the +-180 deg cut
    monkeypatch.setattr(analysis, "ring_phase", lambda s, f: (next(phases), np.radians(2.0), 0.0))
    assert analysis.ring_keeps_timing(steps, 450.0, 0.5)
    # 10 deg apart with u 2 deg: not one timing, unless the ring frequency's u moves them that much (0.2 rad/Hz)
    spread = [0.0, 10.0, 0.0, 10.0, 0.0]
    phases = iter(np.radians(spread))
    monkeypatch.setattr(analysis, "ring_phase", lambda s, f: (next(phases), np.radians(2.0), 0.0))
    assert not analysis.ring_keeps_timing(steps, 450.0, 0.5)
    phases = iter(np.radians(spread))
    monkeypatch.setattr(analysis, "ring_phase", lambda s, f: (next(phases), np.radians(2.0), 0.2))
    assert analysis.ring_keeps_timing(steps, 450.0, 0.5)


def test_a_late_ring_that_loses_less_motion_than_play_held_at_the_dead_centres_is_the_link(rings_read_on):
    """A link on a rail whose friction turns over sharply (3 mm/s) and holds 1.5 times its sliding value at rest
    sticks at each dead centre until the stretched link breaks it free: its ring grows with speed and comes a fixed
    crank angle late, as play's knock does (held-out 450 Hz link: about 0.5 um lost, 0.01 rad).  But play waits at a
    dead centre only when the rail's friction outweighs the slider's inertia there, and a contact ringing at 450 Hz
    then gives way by at least 2 A_1 (1 - lambda) / (2 pi 450)^2 (6.4 um at 10 Hz): 0.5 um cannot be play held
    there.  On main it was named play."""
    rings_read_on(0.5)
    c_ring = c_of(450.0)
    c, u_c = 0.4 * c_ring, 0.45 * c_ring
    growing = [0.02 * f**1.5 for f in SPEEDS]
    stick = float(np.sqrt(2 * 0.5e-6 / RADIUS))
    assert not analysis.ring_keeps_timing(flagged_steps(growing, delay_rad=stick), 450.0, 0.5)   # late, like play
    assert analysis._is_link_ringing(flagged_steps(growing, delay_rad=stick, lost_m=0.5e-6), c, u_c)
    # braked play: 10 um of gap and the contact's give under the friction that holds the slider (22 um in all)
    assert not analysis._is_link_ringing(flagged_steps(growing, delay_rad=0.07, lost_m=22e-6), c, u_c)
    # a lost motion known too poorly to tell stays play, and so does one read without a third harmonic
    assert not analysis._is_link_ringing(flagged_steps(growing, delay_rad=stick, lost_m=0.5e-6, u_a3=1.0), c, u_c)
    assert not analysis._is_link_ringing(flagged_steps(growing, delay_rad=stick, lost_m=0.5e-6, harmonics=2), c, u_c)


def test_the_lost_motion_bound_is_the_contacts_give_under_the_slider_inertia_at_the_outer_dead_centre():
    """2 A_1 (1 - lambda) / (2 pi f_ring)^2 at each step: at 10 Hz and 450 Hz, 6.4 um; a lost motion 5 u below it at
    the fastest step alone is enough, one 2 u below at every step is not (the test is at 1e-3 over the steps)."""
    omega2 = (2 * np.pi * 10.0) ** 2
    bound = 2 * RADIUS * omega2 * (1 - RADIUS / ROD) / (2 * np.pi * 450.0) ** 2
    assert bound == pytest.approx(6.4e-6, rel=0.01)
    u_a3 = 0.002
    u_lost = analysis.play_from_third(u_a3, omega2)
    fast = flagged_steps([1.0] * 5, lost_m=bound - 5 * u_lost, u_a3=u_a3)[-1:]
    assert analysis.lost_motion_below_hold(fast, 450.0, 0.0)
    near = flagged_steps([1.0] * 5, lost_m=bound - 2 * u_lost, u_a3=u_a3)[-1:]
    assert not analysis.lost_motion_below_hold(near, 450.0, 0.0)


def test_the_trend_and_the_ring_give_one_compliance_by_their_weights_widened_when_they_disagree():
    c_ring = c_of(450.0)
    u_ring = c_ring * np.hypot(2 * 0.5 / 450.0, analysis.RING_RESONANCE_U)
    # a trend agreeing with the ring, 10 times less precise: the ring's value, its u a little below the ring's
    c, u = analysis.compliance_with_ring(c_ring, 10 * u_ring, 450.0, 0.5)
    assert c == pytest.approx(c_ring) and u == pytest.approx(u_ring / np.sqrt(1.01))
    # weights 1 : 1 and the two 4 combined u apart (chi-square 16 on one dof): the middle, u widened by 4
    c, u = analysis.compliance_with_ring(c_ring + 4 * np.sqrt(2) * u_ring, u_ring, 450.0, 0.5)
    assert c == pytest.approx(c_ring + 2 * np.sqrt(2) * u_ring) and u == pytest.approx(4 * u_ring / np.sqrt(2))
    # within their u: not narrowed below the weights' u
    c, u = analysis.compliance_with_ring(c_ring + 0.5 * u_ring, u_ring, 450.0, 0.5)
    assert u == pytest.approx(u_ring / np.sqrt(2))
