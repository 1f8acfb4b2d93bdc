"""Streaming rational resampling (L/M polyphase FIR) for chips run in filter bypass.

Neither chip gives 2000 or 2048 Hz: in bypass they sample at 4 kHz (MPU-9250)
or 4.5 kHz (ICM-20948).  Decimating 4000 -> 2048 Hz (L/M = 64/125) or 4500 ->
2048 Hz (512/1125) needs an anti-alias filter, not sample dropping: a
Kaiser-window FIR designed at the upsampled rate, with the passband to 80 % of
the output Nyquist frequency and ``attenuation_db`` from the output Nyquist
frequency up, run as a polyphase filter so each output costs K = taps / L
multiply-adds per axis.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from scipy import signal


class RationalResampler:
    """Resample a stream by L/M.  Output j sits at input position (j M - D) / L, D = (taps - 1) / 2.

    ``process`` takes consecutive input samples (n, channels) and returns the
    outputs whose whole filter support has arrived, with their positions in
    input samples (counted from the last ``reset``), so a caller can time them
    from the input sample clock exactly.
    """

    def __init__(self, up: int, down: int, attenuation_db: float = 70.0, passband: float = 0.8):
        if up < 1 or down < 1:
            raise ValueError("resampling factors must be positive")
        ratio = Fraction(up, down)
        self.up, self.down = ratio.numerator, ratio.denominator
        self.passthrough = self.up == self.down == 1
        if self.passthrough:
            self.taps_per_phase = 1
            self.delay = 0.0
        else:
            # Frequencies relative to the upsampled Nyquist frequency.
            out_nyquist = min(1.0 / self.up, 1.0 / self.down)
            width = (1.0 - passband) * out_nyquist
            numtaps, beta = signal.kaiserord(attenuation_db, width)
            k = -(-numtaps // self.up)                 # taps per phase, rounded up
            numtaps = k * self.up
            cutoff = (1.0 + passband) / 2.0 * out_nyquist
            h = signal.firwin(numtaps, cutoff, window=("kaiser", beta)) * self.up
            # Phase p uses taps h[p], h[p + L], ...: row p, column m multiplies x[n0 - m];
            # kept reversed, column i multiplies x[n0 - (k - 1) + i] (a window read forwards).
            self._poly = h.reshape(k, self.up).T[:, ::-1].copy()
            self.taps_per_phase = k
            self.delay = (numtaps - 1) / 2.0           # in upsampled samples
        self.reset()

    def reset(self) -> None:
        """Forget the history (after a gap the filter restarts)."""
        self._history: np.ndarray | None = None
        self._consumed = 0      # input samples dropped from the front of the history
        self._next_out = 0      # index of the next output sample

    def process(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Feed inputs (n, c); return (outputs (m, c), input positions (m,))."""
        x = np.asarray(x, dtype=float)
        if self.passthrough:
            first = self._consumed
            self._consumed += len(x)
            return x, np.arange(first, first + len(x), dtype=float)
        hist = x if self._history is None else np.concatenate([self._history, x])
        total = self._consumed + len(hist)          # inputs seen so far
        k = self.taps_per_phase
        # Output j needs input n0 = floor(j M / L) and the k - 1 before it.
        j_first = self._next_out
        # smallest j with n0 >= k - 1 (full support): j M >= (k - 1) L
        j_first = max(j_first, -(-((k - 1) * self.up) // self.down))
        j_last = ((total - 1) * self.up) // self.down   # n0 <= total - 1
        if j_last < j_first:
            self._history = hist
            return np.empty((0, x.shape[1])), np.empty(0)
        j = np.arange(j_first, j_last + 1)
        p = j * self.down
        n0 = p // self.up
        phase = p % self.up
        # Every window of k consecutive inputs, as a strided view (no copy): window s is
        # hist[s:s + k].  Output j reads the window ending at its n0.
        hist = np.ascontiguousarray(hist)
        row, col = hist.strides
        windows = np.ndarray((len(hist) - k + 1, k, hist.shape[1]), dtype=hist.dtype, buffer=hist,
                             strides=(row, row, col))
        y = np.matmul(self._poly[phase][:, None, :], windows[n0 - self._consumed - (k - 1)])[:, 0, :]
        positions = (p - self.delay) / self.up
        self._next_out = j_last + 1
        # Keep only what the next output still needs.
        next_n0 = (self._next_out * self.down) // self.up
        keep_from = max(next_n0 - (k - 1), 0) - self._consumed
        keep_from = min(max(keep_from, 0), len(hist))
        self._history = hist[keep_from:]
        self._consumed += keep_from
        return y, positions


def resampling_ratio(chip_rate: float, requested: float, max_down: int = 4096) -> Fraction:
    """L/M bringing ``chip_rate`` closest to ``requested`` with M <= ``max_down``.

    Exact for the rates people ask for (4000 -> 2000: 1/2, 4000 -> 2048: 64/125,
    4500 -> 2048: 512/1125); anything else is approximated and the caller
    reports the rate it actually delivers.
    """
    target = Fraction(requested).limit_denominator(10**6) / Fraction(chip_rate).limit_denominator(10**6)
    return target.limit_denominator(max_down)
