"""A held-out simulator for the static, wheel, slider-crank and rotary procedures (issue 18's held-out audit).

It shares NO code with ``accelrig.sim`` (nor with anything else in accelrig): numpy and scipy only,
its own trajectories, its own sensor and noise models, its own conventions, written from the
physics and from the file formats in docs/recordings.md.  It writes the files a person would hand
accelrig (CSV with a header row, m/s^2 or counts), so the audit (``bench_heldout.py``) judges the
real commands on them.  Nothing in accelrig may be tuned to its conditions: they exist to find
what the project's own stress benchmark (``bench_stress.py``, built on ``accelrig.sim``) cannot.

Noise (``noise``): white, power-law 1/f^beta by spectral shaping of a record four times longer
than the one kept (so the slow part is not periodic in the record), random walk plus white, AR(1)
(a first-order lag of white noise, stationary from its first sample), alone or under white noise, AR(2) with a spectral peak,
band-limited vibration.  Offset drifts (``drift``): a step, an exponential
warm-up, a sinusoidal thermal cycle, each of a stated total size.

Wheel records may start as an operator's do (``rest_s``, ``push_s``, ``pushes``): the wheel at rest, then a
hand spinning it up with an irregular torque in one or more strokes, then the free coast of ``seconds``.

Truth for offsets: the sensor's offset during the calibration, i.e. its fixed offset plus the mean,
over the samples the procedure uses, of every slow part (the drift and the non-white noise); for the
wheel, over the free coast.  A stationary noise (AR(1), AR(2), a vibration) has a long-run mean of zero: its
mean over the run is an error of the estimate, not part of the truth.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import signal

G = 9.80665


# ----------------------------------------------------------------------------------------------------------
# noise and drift


@dataclass
class Noise:
    """Per-sample noise: ``kind`` one of white, power, walk, ar1, white+ar1, ar2, band.

    sd          white sd per sample (m/s^2), per axis scale ``axis``
    beta        power law exponent (power): PSD(f) = white PSD * (corner / f)^beta
    corner      frequency where the coloured part's PSD equals the white PSD (power), Hz
    walk        random-walk step sd per sqrt(s) (walk), m/s^2/sqrt(s)
    r           AR(1) coefficient per sample (ar1): x_k = r x_k-1 + e_k, marginal sd ``sd``, no white part
    ar_sd       white+ar1: white noise of sd ``sd`` plus an AR(1) part of coefficient ``r`` and marginal sd ``ar_sd``
                (a slow wander under a white floor; stationary, so not in the truth)
    peak, r     AR(2) peak frequency (Hz) and pole radius (ar2); the sd is ``sd``
    band        (low, high) Hz and ``band_sd`` m/s^2 of a vibration added to white noise (band)
    """

    kind: str = "white"
    sd: float = 0.03
    axis: tuple[float, float, float] = (1.0, 1.0, 1.0)
    beta: float = 1.0
    corner: float = 1.0
    walk: float = 0.0
    peak: float = 5.0
    r: float = 0.97
    band: tuple[float, float] = (8.0, 12.0)
    band_sd: float = 0.0
    ar_sd: float = 0.0

    def draw(self, n: int, rate: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(total noise, its slow non-white part) as (n, 3) arrays."""
        scale = np.asarray(self.axis, dtype=float)
        white = rng.standard_normal((n, 3)) * self.sd
        slow = np.zeros((n, 3))
        if self.kind == "white":
            pass
        elif self.kind == "power":
            m = 4 * n
            f = np.fft.rfftfreq(m, 1.0 / rate)
            f[0] = f[1]
            shape = (self.corner / f) ** (self.beta / 2.0)
            spec = np.fft.rfft(rng.standard_normal((m, 3)), axis=0) * shape[:, None]
            long = np.fft.irfft(spec, m, axis=0) * self.sd
            start = int(rng.integers(0, m - n))
            slow = long[start:start + n]
        elif self.kind == "walk":
            slow = np.cumsum(rng.standard_normal((n, 3)), axis=0) * self.walk / np.sqrt(rate)
            slow -= slow[0]
        elif self.kind == "ar1":
            # stationary from the first sample: x_0 drawn with the process' own sd, innovations sd sqrt(1 - r^2)
            e = rng.standard_normal((n, 3)) * np.sqrt(1.0 - self.r**2)
            start = rng.standard_normal(3)
            x = signal.lfilter([1.0], [1.0, -self.r], e, axis=0, zi=(self.r * start)[None, :])[0]
            return x * self.sd * scale, np.zeros((n, 3))
        elif self.kind == "white+ar1":
            e = rng.standard_normal((n, 3)) * np.sqrt(1.0 - self.r**2)
            start = rng.standard_normal(3)
            x = signal.lfilter([1.0], [1.0, -self.r], e, axis=0, zi=(self.r * start)[None, :])[0]
            return (white + x * self.ar_sd) * scale, np.zeros((n, 3))
        elif self.kind == "ar2":
            # x_k = 2 r cos(w) x_k-1 - r^2 x_k-2 + e_k, scaled to sd; replaces the white part
            w = 2 * np.pi * self.peak / rate
            a = [1.0, -2 * self.r * np.cos(w), self.r ** 2]
            e = rng.standard_normal((n + 2000, 3))
            x = signal.lfilter([1.0], a, e, axis=0)[2000:]
            x *= self.sd / x.std(axis=0)
            return x * scale, np.zeros((n, 3))
        elif self.kind == "band":
            sos = signal.butter(4, self.band, btype="bandpass", fs=rate, output="sos")
            e = rng.standard_normal((n + 4000, 3))
            x = signal.sosfilt(sos, e, axis=0)[4000:]
            slow = x * self.band_sd / x.std(axis=0)
            # a vibration is not slow: it is noise that is not white, judged as noise (not in the truth)
            return (white + slow) * scale, np.zeros((n, 3))
        else:
            raise ValueError(self.kind)
        return (white + slow) * scale, slow * scale


@dataclass
class Drift:
    """An offset change over time, m/s^2 per axis direction ``direction`` (unit, drawn if None)."""

    kind: str = "none"       # none, step, warmup, thermal
    size: float = 0.0        # total change (step, warmup) or peak-to-peak (thermal)
    at: float = 0.5          # step: share of the run; warmup: time constant as a share; thermal: period share
    direction: np.ndarray | None = None

    def at_times(self, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        if self.kind == "none" or self.size == 0.0:
            return np.zeros((t.size, 3))
        d = self.direction if self.direction is not None else rng.normal(size=3)
        d = np.asarray(d, float) / np.linalg.norm(d)
        span = t[-1] - t[0]
        x = (t - t[0]) / span
        if self.kind == "step":
            where = float(rng.uniform(0.3, 0.7))
            shape = (x >= where).astype(float)
        elif self.kind == "warmup":
            shape = -np.expm1(-x / self.at) / -np.expm1(-1.0 / self.at)
        elif self.kind == "thermal":
            phase = float(rng.uniform(0, 2 * np.pi))
            shape = 0.5 * np.sin(2 * np.pi * x / self.at + phase)
        else:
            raise ValueError(self.kind)
        return shape[:, None] * self.size * d[None, :]


def rotation(axis_angles: np.ndarray) -> np.ndarray:
    """Rotation matrix from a rotation vector (Rodrigues)."""
    v = np.asarray(axis_angles, float)
    a = np.linalg.norm(v)
    if a < 1e-15:
        return np.eye(3)
    k = v / a
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * kx + (1 - np.cos(a)) * kx @ kx


def write_csv(path: Path, t: np.ndarray | None, columns: dict[str, np.ndarray], meta: dict | None = None,
              fmt: str = "%.6f") -> None:
    names = (["t"] if t is not None else []) + list(columns)
    data = np.column_stack(([t] if t is not None else []) + list(columns.values()))
    with open(path, "w") as fh:
        if meta:
            fh.write("# accelrig-meta: " + json.dumps(meta) + "\n")
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, data, fmt=["%.9f"] * (t is not None) + [fmt] * len(columns), delimiter=",")


# ----------------------------------------------------------------------------------------------------------
# static: faces held by hand, with handling between


FACES = {"+x": (0, -1), "-x": (0, 1), "+y": (1, -1), "-y": (1, 1), "+z": (2, -1), "-z": (2, 1)}
WIZARD = ("+z", "-z", "+x", "-x", "+y", "-y", "+z", "+x", "+y", "-z", "-x", "-y", "+z", "+x", "+y")   # the TUI wizard's order


@dataclass
class StaticCase:
    rate: float = 200.0
    hold: tuple[float, float] = (4.5, 6.0)     # each hold's length drawn uniformly, s
    move: tuple[float, float] = (1.5, 2.5)     # handling between holds, s
    tilt_deg: float = 0.1                      # hand tilt sd per component
    order: tuple[str, ...] = WIZARD
    noise: Noise = field(default_factory=Noise)
    drift: Drift = field(default_factory=Drift)
    g: float = G
    range_g: float = 2.0


def _up_for(face: str, tilt_deg: float, rng: np.random.Generator) -> np.ndarray:
    axis, sign = FACES[face]
    up = np.zeros(3)
    up[axis] = sign            # "+z down": z points down, the up direction is -z
    return rotation(np.radians(tilt_deg) * rng.standard_normal(3)) @ up


def simulate_static(case: StaticCase, rng: np.random.Generator):
    """Returns (t, raw (n, 3) in m/s^2, truth dict with C, b and hold intervals)."""
    gains = 1.0 + 0.02 * rng.standard_normal(3)
    mount = rotation(np.radians(0.5) * rng.standard_normal(3))
    k = mount.T @ np.diag(1.0 / gains)                 # raw = K f + o, calibrated = C (raw - o), C = K^-1
    offset = 0.3 * rng.standard_normal(3)
    dt = 1.0 / case.rate
    pieces_f, holds = [], []
    t_now = 0.0
    prev = None

    def hand(n):   # the hand's own acceleration while handling: smooth, about 1 m/s^2
        sos = signal.butter(2, 4.0, fs=case.rate, output="sos")
        x = signal.sosfilt(sos, rng.standard_normal((n + 200, 3)), axis=0)[200:]
        return x / x.std(axis=0) * 1.2

    for face in case.order:
        up = _up_for(face, case.tilt_deg, rng)
        n_move = int(rng.uniform(*case.move) * case.rate)
        start_up = prev if prev is not None else _up_for(case.order[-1], 5.0, rng)
        mid = start_up + up
        if np.linalg.norm(mid) < 0.3:                  # opposite faces: turn through a perpendicular
            mid = np.cross(up, rng.normal(size=3))
        mid /= np.linalg.norm(mid)
        s = 0.5 - 0.5 * np.cos(np.pi * np.arange(n_move) / n_move)
        path = np.where(s[:, None] < 0.5, (1 - 2 * s)[:, None] * start_up + (2 * s)[:, None] * mid,
                        (2 - 2 * s)[:, None] * mid + (2 * s - 1)[:, None] * up)
        path /= np.linalg.norm(path, axis=1, keepdims=True)
        pieces_f.append(case.g * path + hand(n_move) * np.sin(np.pi * np.arange(n_move) / n_move)[:, None])
        t_now += n_move * dt
        n_hold = int(rng.uniform(*case.hold) * case.rate)
        pieces_f.append(np.tile(case.g * up, (n_hold, 1)))
        holds.append((t_now, t_now + n_hold * dt))
        t_now += n_hold * dt
        prev = up
    n_end = int(1.5 * case.rate)
    pieces_f.append(case.g * prev + hand(n_end) * np.sin(np.pi * np.arange(n_end) / n_end)[:, None])
    f = np.concatenate(pieces_f)
    n = f.shape[0]
    t = np.arange(n) * dt
    noise, slow = case.noise.draw(n, case.rate, rng)
    drift = case.drift.at_times(t, rng)
    raw = f @ k.T + offset + drift + noise
    scale = case.range_g * G / 32768.0
    raw = np.clip(np.rint(raw / scale), -32768, 32767) * scale
    used = np.zeros(n, dtype=bool)
    for a, b in holds:                                 # the still samples a procedure would keep
        used |= (t >= a + 0.3) & (t <= b - 0.5)
    b_true = offset + (drift + slow)[used].mean(axis=0)
    return t, raw, {"C": np.linalg.inv(k), "b": b_true, "holds": holds, "scale": scale}


# ----------------------------------------------------------------------------------------------------------
# wheel: a tilted wheel coasting down


@dataclass
class WheelCase:
    rate: float = 200.0
    seconds: float = 90.0
    radius: float = 0.28
    tilt_deg: float = 45.0
    omega0: float = 9.0
    # speed law: "cubic" (w0 + w1 t + w2 t^2 + w3 t^3, the paper's), or friction "viscous+coulomb",
    # "quadratic+coulomb" (aerodynamic drag), with the loss over the run ``slow_to`` (share of omega0 left)
    law: str = "cubic"
    slow_to: float = 0.55
    coulomb_share: float = 0.5     # share of the initial deceleration that is Coulomb (speed-independent)
    tilt_wander_deg: float = 0.0   # the stand creeps: tilt changes linearly by this over the run
    wobble_deg: float = 0.0        # bearing play: the axis nods by this once per turn
    # the axis moving in space, modelled as a rigid wheel turning about an axis that itself turns (``_moving_axis``):
    # ``axis_deg`` its amplitude; ``axis_motion`` "nod" (back and forth about one line, in a plane drawn at random,
    # ``axis_per_turn`` times per turn) or "cone" (the axis circles round its mean once per turn, in the sense the
    # wheel turns, ``axis_sense`` +1, or against it, -1); ``axis_above`` a speed (rad/s) below which the axis
    # holds still (play that opens only when the wheel runs fast), the amplitude fading in over 0.5 rad/s
    axis_deg: float = 0.0
    axis_motion: str = "nod"
    axis_per_turn: int = 1
    axis_sense: int = 1
    axis_above: float = 0.0
    noise: Noise = field(default_factory=lambda: Noise(sd=0.08))
    drift: Drift = field(default_factory=Drift)
    range_g: float = 4.0
    # what an operator's record holds before the free coast (``seconds`` long): the wheel at rest for
    # ``rest_s``, then the hand spins it up from 0 to omega0 over ``push_s`` with an irregular torque,
    # in ``pushes`` strokes (the hand lets go and grabs again between them)
    rest_s: float = 0.0
    push_s: float = 0.0
    pushes: int = 1


def _push(case: WheelCase, x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Speed over the push, x in [0, 1] its share of the push: 0 -> omega0.  The hand's torque is a train
    of ``pushes`` strokes of random lengths and strengths (each a sin^2 bump), with a slow random tremor
    on top; between strokes nothing drives the wheel (the hand goes back)."""
    k = max(int(case.pushes), 1)
    lengths = rng.uniform(0.6, 1.0, k)
    gaps = rng.uniform(0.1, 0.3, k - 1) if k > 1 else np.zeros(0)
    total = lengths.sum() + gaps.sum()
    lengths, gaps = lengths / total, gaps / total
    torque = np.zeros_like(x)
    start = 0.0
    for i in range(k):
        inside = (x >= start) & (x < start + lengths[i])
        s = (x[inside] - start) / lengths[i]
        tremor = 1.0 + 0.4 * np.sin(2 * np.pi * rng.uniform(1.5, 4.0) * s + rng.uniform(0, 2 * np.pi))
        torque[inside] = rng.uniform(0.5, 1.5) * np.sin(np.pi * s) ** 2 * tremor
        start += lengths[i] + (gaps[i] if i < k - 1 else 0.0)
    speed = np.concatenate([[0.0], np.cumsum(0.5 * (torque[1:] + torque[:-1]) * np.diff(x))])
    return case.omega0 * speed / speed[-1]


def _speed(case: WheelCase, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    w0, T = case.omega0, case.seconds
    if case.law == "cubic":
        # a gentle coast-down that a cubic holds exactly, with a random shape
        x = t / T
        c2 = rng.uniform(-0.1, 0.1)
        c3 = rng.uniform(-0.05, 0.05)
        w = w0 * (1 - (1 - case.slow_to) * x + c2 * x * (1 - x) + c3 * x * (1 - x) * (0.5 - x))
        return w
    # integrate dw/dt = -c - k w (viscous) or -c - q w^2 (quadratic), choosing k or q and c so that
    # w(T) = slow_to * w0 and the Coulomb part is coulomb_share of the initial deceleration
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq

    def run(drag, c, times):
        if case.law == "viscous+coulomb":
            f = (lambda _t, w: -c - drag * w)
        else:
            f = (lambda _t, w: -c - drag * w * w)
        return solve_ivp(f, (0, T), [w0], t_eval=times, rtol=1e-11, atol=1e-12).y[0]

    def end_error(total):   # total initial deceleration
        c = case.coulomb_share * total
        drag = (1 - case.coulomb_share) * total / (w0 if case.law == "viscous+coulomb" else w0 * w0)
        return run(drag, c, [T])[-1] - case.slow_to * w0

    total = brentq(end_error, 1e-6, w0 / T * 3)
    c = case.coulomb_share * total
    drag = (1 - case.coulomb_share) * total / (w0 if case.law == "viscous+coulomb" else w0 * w0)
    return run(drag, c, t)


def _moving_axis(case: WheelCase, t: np.ndarray, theta: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """What the sensor feels (n, 3, in the wheel's frame) on a rigid wheel whose axis moves in space.

    No formula for the acceleration: the wheel's attitude in space is a rotation matrix, B = N(t) T R(theta)
    (R the wheel's turn about its own axis, T the tilt, N the axis' own small rotation about the hub's centre),
    the sensor's place is B (-r, 0, 0), and its acceleration is that place differentiated twice in time
    (five-point stencil on a grid 16 times finer than the samples, the wheel angle interpolated by a cubic
    spline); the sensor reads that acceleration plus gravity's reaction, both seen in B.  With N fixed this is
    the same wheel as the other rows: X towards the axis, Y along the motion, Z along the axis."""
    from scipy.interpolate import CubicSpline

    oversample = 16
    h = (t[1] - t[0]) / oversample
    angle = CubicSpline(t, theta)                    # extrapolated smoothly over the stencil's two ends
    fine = t[0] - 2 * h + np.arange((t.size - 1) * oversample + 5) * h
    th = angle(fine)
    tilt = rotation(np.array([0.0, np.radians(case.tilt_deg), 0.0]))
    u1, u2 = tilt[:, 0], tilt[:, 1]                  # two directions square to the mean axis tilt[:, 2]
    size = np.full(fine.size, np.radians(case.axis_deg))
    if case.axis_above:
        size *= np.clip((np.abs(angle(fine, 1)) - case.axis_above) / 0.5 + 0.5, 0.0, 1.0)
    c = rng.uniform(0, 2 * np.pi)
    if case.axis_motion == "nod":
        psi = rng.uniform(0, 2 * np.pi)
        line = np.cos(psi) * u1 + np.sin(psi) * u2
        vec = (size * np.cos(case.axis_per_turn * th + c))[:, None] * line[None, :]
    elif case.axis_motion == "cone":
        # the wheel turns by -theta about its axis (below): the axis circling in its sense runs round by -theta
        a = -case.axis_sense * th + c
        vec = size[:, None] * (np.cos(a)[:, None] * u1[None, :] + np.sin(a)[:, None] * u2[None, :])
    else:
        raise ValueError(case.axis_motion)
    # B = N T Rz(-theta): the wheel turns about its axis by -theta, which puts X towards the axis and Y along
    # the motion for a sensor at (-r, 0, 0) (gravity's up in B: (-sin a cos theta, -sin a sin theta, cos a))
    ct, st = np.cos(th), np.sin(th)
    spin = np.zeros((fine.size, 3, 3))
    spin[:, 0, 0], spin[:, 0, 1], spin[:, 1, 0], spin[:, 1, 1], spin[:, 2, 2] = ct, st, -st, ct, 1.0
    attitude = np.einsum("nij,jk,nkl->nil", _rotations(vec), tilt, spin)
    place = attitude[:, :, 0] * -case.radius
    acc = (-place[4:] + 16 * place[3:-1] - 30 * place[2:-2] + 16 * place[1:-3] - place[:-4]) / (12 * h * h)
    keep = np.arange(t.size) * oversample            # fine[2 + keep] are the sample times
    felt = acc[keep] + np.array([0.0, 0.0, G])
    return np.einsum("nji,nj->ni", attitude[2 + keep], felt)


def _rotations(vec: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) from rotation vectors (n, 3) (Rodrigues)."""
    a = np.linalg.norm(vec, axis=1)
    k = vec / np.where(a > 0, a, 1.0)[:, None]
    kx = np.zeros((vec.shape[0], 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx -= np.transpose(kx, (0, 2, 1))
    return (np.eye(3)[None] + np.sin(a)[:, None, None] * kx
            + (1 - np.cos(a))[:, None, None] * np.einsum("nij,njk->nik", kx, kx))


def simulate_wheel(case: WheelCase, rng: np.random.Generator):
    before = case.rest_s + case.push_s     # the free coast starts here
    n = int((before + case.seconds) * case.rate)
    t = np.arange(n) / case.rate
    free = t >= before - 1e-9
    w = np.zeros(n)
    w[free] = _speed(case, t[free] - before, rng)
    pushed = (t >= case.rest_s) & ~free
    if case.push_s > 0:
        x = np.append((t[pushed] - case.rest_s) / case.push_s, 1.0)
        w[pushed] = _push(case, x, rng)[:-1]
    # the angle integrates the speed; the tangential r dw/dt and centripetal r w^2 act through the push too
    dw = np.gradient(w, t, edge_order=2)
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))]) + rng.uniform(0, 2 * np.pi)
    alpha = np.radians(case.tilt_deg + case.tilt_wander_deg * (t / case.seconds - 0.5))
    alpha = alpha + np.radians(case.wobble_deg) * np.cos(theta)
    if case.axis_deg:
        f = _moving_axis(case, t, theta, rng)
    else:
        # wheel frame: X towards the axis, Y along the motion, Z along the axis; up in it:
        up = np.column_stack([-np.sin(alpha) * np.cos(theta), -np.sin(alpha) * np.sin(theta), np.cos(alpha)])
        f = G * up
        f[:, 0] += case.radius * w * w
        f[:, 1] += case.radius * dw
    gains = 1.0 + 0.015 * rng.standard_normal(3)
    angles = np.radians(rng.uniform(18, 32, 3) * rng.choice([-1, 1], 3))
    mount = rotation(angles)
    offset = 0.25 * rng.standard_normal(3)
    noise, slow = case.noise.draw(n, case.rate, rng)
    drift = case.drift.at_times(t, rng)
    raw = f @ (np.diag(gains) @ mount).T + offset + drift + noise
    scale = case.range_g * G / 32768.0
    raw = np.clip(np.rint(raw / scale), -32768, 32767) * scale
    # the procedure calibrates from the free coast: the offset's slow parts are averaged over it
    return t, raw, {"gain": gains, "offset": offset + (drift + slow)[free].mean(axis=0),
                    "tilt_deg": float(np.degrees(alpha[free].mean())), "scale": scale, "coast_from": before}


# ----------------------------------------------------------------------------------------------------------
# rotary: an encoder-driven disk oscillating about a vertical axis


@dataclass
class RotaryCase:
    nominal_rate: float = 1660.0
    seconds: float = 20.0
    radius: float = 0.170
    plan: tuple[tuple[float, float], ...] = ((4.0, 40.0), (6.0, 24.0), (7.0, 14.0), (10.0, 7.0))  # Hz, deg p-p
    harmonic2: float = 0.0          # relative amplitude of a 2nd harmonic in the disk's motion
    encoder_step_deg: float = 0.01  # encoder resolution
    eccentric_rad: float = 0.0      # encoder disk eccentricity: theta_read = theta + e sin(theta + phase)
    jitter_s: float = 0.0           # MEMS sample-time jitter sd (white), s
    clock_wander: float = 0.0       # MEMS clock: random walk of the rate, relative sd per sqrt(s)
    noise: Noise = field(default_factory=Noise)
    range_g: float = 8.0


def simulate_rotary(case: RotaryCase, rng: np.random.Generator):
    """Returns (mems counts (n, 3), encoder t, theta, truth: rate, sensitivities per axis)."""
    f0, pp = case.plan[int(rng.integers(len(case.plan)))]
    theta0 = np.radians(pp / 2.0)
    phase = rng.uniform(-np.pi, np.pi)
    phase2 = rng.uniform(-np.pi, np.pi)
    w = 2 * np.pi * f0

    def motion(t):
        """theta, theta', theta''."""
        a1 = w * t + phase
        a2 = 2 * w * t + phase2
        h = case.harmonic2
        th = theta0 * (np.cos(a1) + h * np.cos(a2))
        d1 = -theta0 * (w * np.sin(a1) + 2 * w * h * np.sin(a2))
        d2 = -theta0 * (w * w * np.cos(a1) + 4 * w * w * h * np.cos(a2))
        return th, d1, d2

    true_rate = case.nominal_rate * (1 + rng.uniform(0.002, 0.005) * rng.choice([-1, 1]))
    n = int(case.seconds * case.nominal_rate)
    k = np.arange(n)
    if case.clock_wander:
        rel = np.cumsum(rng.standard_normal(n)) * case.clock_wander / np.sqrt(true_rate)
        t = np.concatenate([[0.0], np.cumsum(1.0 / (true_rate * (1 + rel[:-1])))])
    else:
        t = k / true_rate
    t = t + 0.05 + (rng.standard_normal(n) * case.jitter_s if case.jitter_s else 0.0)
    _, d1, d2 = motion(t)
    force = np.column_stack([case.radius * d2, case.radius * d1 * d1, np.full(n, G)])  # x along, y to the axis, z up
    scale = case.range_g * G / 32768.0
    sens = (1.0 / scale) * (1.0 + 0.012 * rng.standard_normal(3) + 0.012)
    cross = 0.001 * rng.standard_normal((3, 3))
    np.fill_diagonal(cross, 0.0)
    resp = np.diag(sens) @ (np.eye(3) + cross)
    offset = rng.normal(0, 0.2, 3) / scale
    noise, _ = case.noise.draw(n, case.nominal_rate, rng)
    counts = force @ resp.T + offset + noise @ np.diag(sens).T
    counts = np.clip(np.rint(counts), -32768, 32767)
    te = np.arange(int(case.seconds * 1000.0) + 100) / 1000.0
    th, _, _ = motion(te)
    read = th + case.eccentric_rad * np.sin(th + rng.uniform(0, 2 * np.pi))
    step = np.radians(case.encoder_step_deg)
    read = np.rint(read / step) * step
    return counts, te, read, {"rate": true_rate, "S_x": sens[0], "S_y": sens[1], "frequency": f0}


# ----------------------------------------------------------------------------------------------------------
# slider-crank: a motor turns a crank at speed steps, a rod drives a slider carrying the sensor


@dataclass
class SliderCase:
    """A slider-crank stand, written from the geometry and Newton's law (no formula for the acceleration).

    The crank angle phi(t) is the integral of the motor speed on a fine time grid (``oversample`` points
    per sample); the pin's position is the exact law x = r cos phi + sqrt(l^2 - r^2 sin^2 phi).  A rigid
    link: the slider's acceleration is that position differentiated twice by a five-point stencil on
    the fine grid.  A link with play or compliance: the slider is a mass on a rail with Coulomb and
    viscous friction, driven through the link (a dead zone with a stiff, lightly damped contact at each
    side, or a spring-damper), integrated on the fine grid; its acceleration is the net force over the
    mass.  The sensor low-passes at ``bandwidth`` (2nd-order Butterworth, causal) and samples every
    ``oversample``-th point.

    steps, seconds, settle  speed steps (Hz), steady seconds per step, a cosine speed ramp between them
                            (``step`` column -1; the first step starts already turning)
    eccentric               the crank pin sits off its nominal place by this much (m), in a random
                            direction: the effective radius |r + e| is the truth, r the caliper's
    wobble, wobble_hz       a sinusoidal speed ripple (relative amplitude, Hz, random phase)
    wander, wander_hz       a random speed wander: Gaussian, relative sd, low-passed at wander_hz (4th order)
    cogging, cogging_n      a motor torque ripple at cogging_n per turn: angular acceleration amplitude rad/s^2
                            (its speed ripple shrinks as 1/omega^2, as inertia filters a torque)
    dead_zone               play in the rod-to-slider pin, m (total width): the slider crosses it in free
                            flight on the rail whenever the force through the link would reverse, then
                            hits the other side (a contact at contact_hz, damping ratio contact_zeta)
    link_hz, link_zeta      a compliant link: spring-damper between rod and slider (resonance link_hz);
                            0 = rigid.  Friction reversing at the dead centres excites it twice per turn
    friction                Coulomb friction of the rail over the slider's weight (mu), viscous ``damping`` 1/s;
                            a preloaded (braked) slide has mu well above 1: then the slider's inertia never
                            outweighs it and play is crossed where the velocity reverses, at the dead centres
    breakaway, stribeck_v   Stribeck friction: at rest the rail holds ``breakaway`` times the sliding friction,
                            falling to it over speeds of about ``stribeck_v`` (m/s); 1 = plain Coulomb
    reversal_v              the speed band over which the friction's direction turns (m/s): a hard contact
                            reverses within about 1 mm/s, a greased or polymer slide over tens of mm/s (its
                            lubricant film and the contact's elastic pre-sliding carry the force meanwhile)
    misalign_deg            the sensor sits rotated by this much on the slider (about a random axis)
    """

    rate: float = 2048.0
    oversample: int = 8
    radius: float = 0.0080
    rod: float = 0.0420
    clearance: float = 1e-4
    steps: tuple[float, ...] = (3.0, 4.5, 6.5, 8.5, 10.0)
    seconds: float = 1.25
    settle: float = 0.4
    eccentric: float = 0.0
    wobble: float = 0.0
    wobble_hz: float = 5.0
    wander: float = 0.0
    wander_hz: float = 1.5
    cogging: float = 0.0
    cogging_n: int = 6
    dead_zone: float = 0.0
    contact_hz: float = 450.0
    contact_zeta: float = 0.1
    link_hz: float = 0.0
    link_zeta: float = 0.05
    mass: float = 0.05
    friction: float = 0.15
    breakaway: float = 1.0
    stribeck_v: float = 0.01
    reversal_v: float = 1e-3
    damping: float = 0.5
    misalign_deg: float = 0.5
    bandwidth: float = 450.0
    noise: Noise = field(default_factory=lambda: Noise(sd=0.08))
    range_g: float = 8.0


def _speed_profile(case: SliderCase, t: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(crank speed rad/s on the fine grid ``t``, evenly spaced, step index per point: -1 while settling)."""
    w = np.full_like(t, 2 * np.pi * case.steps[0])    # before t = 0: already turning at the first speed
    index = np.full(t.size, -1)
    edge = 0.0
    previous = case.steps[0]
    for i, hz in enumerate(case.steps):
        ramp = (t >= edge) & (t < edge + case.settle)
        x = (t[ramp] - edge) / case.settle
        w[ramp] = 2 * np.pi * (previous + (hz - previous) * (0.5 - 0.5 * np.cos(np.pi * x)))
        edge += case.settle
        steady = (t >= edge) & (t < edge + case.seconds) if i < len(case.steps) - 1 else t >= edge
        w[steady] = 2 * np.pi * hz
        index[steady] = i
        edge += case.seconds
        previous = hz
    relative = np.zeros_like(t)
    if case.wobble:
        relative += case.wobble * np.sin(2 * np.pi * case.wobble_hz * t + rng.uniform(0, 2 * np.pi))
    if case.wander:
        fs = (t.size - 1) / (t[-1] - t[0])
        sos = signal.butter(4, case.wander_hz, fs=fs, output="sos")
        pad = int(4 * fs / case.wander_hz)
        x = signal.sosfilt(sos, rng.standard_normal(t.size + pad))[pad:]
        relative += case.wander * x / x.std()
    return w * (1.0 + relative), index


def _second_derivative(x: np.ndarray, h: float) -> np.ndarray:
    """Five-point central stencil (error h^4 x^(6) / 90); the two points at each end are left at the next."""
    d = np.empty_like(x)
    d[2:-2] = (-x[4:] + 16 * x[3:-1] - 30 * x[2:-2] + 16 * x[1:-3] - x[:-4]) / (12 * h * h)
    d[:2], d[-2:] = d[2], d[-3]
    return d


def rail_friction(case: SliderCase, v: float, sliding: float) -> float:
    """The rail's dry friction on a slider moving at v (N): ``sliding`` N when sliding fast, up to ``breakaway`` times
    that near rest (falling over about ``stribeck_v``: a Gaussian Stribeck curve), its direction turning over
    about ``reversal_v`` (a tanh)."""
    level = sliding * (1.0 + (case.breakaway - 1.0) * math.exp(-(v / case.stribeck_v) ** 2))
    return level * math.tanh(v / case.reversal_v)


def _driven_slider(case: SliderCase, pin: np.ndarray, h: float) -> np.ndarray:
    """The slider's acceleration when driven through play or a spring: semi-implicit Euler on the fine grid.

    Forces on the slider: the link (dead zone: a contact spring-damper acting only while the pin presses on
    a side; compliance: a spring-damper always), the rail's friction (``rail_friction``) and viscous friction.
    Returns the net force over the mass at each grid point.
    """
    m = case.mass
    pin_v = np.gradient(pin, h)
    if case.dead_zone > 0:
        k = m * (2 * np.pi * case.contact_hz) ** 2
        c = 2 * case.contact_zeta * np.sqrt(k * m)
        half = 0.5 * case.dead_zone
    else:
        k = m * (2 * np.pi * case.link_hz) ** 2
        c = 2 * case.link_zeta * np.sqrt(k * m)
        half = 0.0
    coulomb = case.friction * m * G
    viscous = case.damping * m
    s, v = float(pin[0]), float(pin_v[0])
    acc = np.empty_like(pin)
    for i in range(pin.size):
        gap = s - float(pin[i])
        rel_v = v - float(pin_v[i])
        if half > 0:
            if gap > half:
                force = -k * (gap - half) - c * rel_v
                force = min(force, 0.0)      # a contact pushes, never pulls
            elif gap < -half:
                force = -k * (gap + half) - c * rel_v
                force = max(force, 0.0)
            else:
                force = 0.0
        else:
            force = -k * gap - c * rel_v
        force -= rail_friction(case, v, coulomb) + viscous * v
        a = force / m
        acc[i] = a
        v += a * h
        s += v * h
    return acc


def simulate_slider(case: SliderCase, rng: np.random.Generator):
    """Returns (t, acc (n, 3) m/s^2 as the sensor reads it, step column, truth).

    truth: ``radius`` (the effective crank radius, what the motion shows), ``speed`` per step (mean crank
    rate over the step's first to last sample, Hz), ``rod``.
    """
    total = case.settle * len(case.steps) + case.seconds * len(case.steps)
    lead = 0.3                                  # the dynamics and the sensor's filter settle before t = 0
    h = 1.0 / (case.rate * case.oversample)
    n = int(round(total * case.rate))
    t_fine = np.arange(-int(lead / h), n * case.oversample + 4) * h
    w, index = _speed_profile(case, t_fine, rng)
    phi = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * h)]) + rng.uniform(0, 2 * np.pi)
    if case.cogging:
        # J phi'' = T sin(N phi): at steady speed the angle lags by (T/J) / (N omega)^2 sin(N phi)
        phase = rng.uniform(0, 2 * np.pi)
        phi = phi - case.cogging / (case.cogging_n * w) ** 2 * np.sin(case.cogging_n * phi + phase)
    psi = rng.uniform(0, 2 * np.pi)
    radius = float(np.hypot(case.radius + case.eccentric * np.cos(psi), case.eccentric * np.sin(psi)))
    pin = radius * np.cos(phi) + np.sqrt(case.rod ** 2 - (radius * np.sin(phi)) ** 2)
    if case.dead_zone > 0 or case.link_hz > 0:
        along = _driven_slider(case, pin, h)
    else:
        along = _second_derivative(pin, h)
    sos = signal.butter(2, case.bandwidth, fs=1.0 / h, output="sos")
    along = signal.sosfilt(sos, along)
    start = int(lead / h)
    keep = start + np.arange(n) * case.oversample
    t = t_fine[keep]
    t = t - t[0]
    f = np.zeros((n, 3))
    f[:, 0] = along[keep]
    f[:, 2] = G                                  # the rail is level: the sensor's z feels gravity (up)
    axis = rng.normal(size=3)
    mount = rotation(np.radians(case.misalign_deg) * axis / np.linalg.norm(axis))
    offset = 0.1 * rng.standard_normal(3)
    noise, _ = case.noise.draw(n, case.rate, rng)
    acc = f @ mount.T + offset + noise
    scale = case.range_g * G / 32768.0
    acc = np.clip(np.rint(acc / scale), -32768, 32767) * scale
    step = index[keep]
    speeds = []
    for i in range(len(case.steps)):
        at = keep[step == i]
        speeds.append(float((phi[at[-1]] - phi[at[0]]) / (2 * np.pi * (t_fine[at[-1]] - t_fine[at[0]]))))
    return t, acc, step, {"radius": radius, "speed": speeds, "rod": case.rod, "scale": scale}
