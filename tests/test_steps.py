"""The shared step capture: marked and timed steps, and any chunking of one stream gives the same steps."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from accelrig.errors import DataError
from accelrig.procedures.steps import StepCapture
from accelrig.recording import Recording

RATE = 100.0


def stream(step_values) -> Recording:
    n = len(step_values)
    t = np.arange(n) / RATE
    acc = np.column_stack([t, 2 * t, 3 * t])
    return Recording(t, acc, "m/s^2", {"step": np.asarray(step_values, dtype=float), "theta": -t})


def cut(rec: Recording, sizes) -> list[Recording]:
    """The stream in chunks of the given sizes (the rest in one last chunk)."""
    edges = np.cumsum([0, *sizes])
    edges = edges[edges < len(rec)].tolist() + [len(rec)]
    return [rec.slice(a, b) for a, b in pairwise(edges)]


def as_tuples(steps):
    return [(s.index, s.recording.t.tolist(), s.recording.acc.tolist(), s.recording.channels["theta"].tolist())
            for s in steps]


# runs of (value, length): settling (-1) between steps, each step index once, in order
runs = st.lists(st.integers(1, 30), min_size=1, max_size=5).map(
    lambda lengths: [v for i, n in enumerate(lengths) for v in [-1] * (i % 2 + 1) + [i] * n] + [-1])


@settings(max_examples=60, deadline=None)
@given(values=runs, sizes=st.lists(st.integers(1, 40), max_size=30))
def test_marked_steps_do_not_depend_on_the_chunking(values, sizes):
    rec = stream(values)
    whole = StepCapture()
    expected = whole.feed(rec) + whole.finish()
    chunked = StepCapture()
    got = [step for chunk in cut(rec, sizes) for step in chunked.feed(chunk)] + chunked.finish()
    assert as_tuples(got) == as_tuples(expected)
    assert [s.index for s in got] == sorted(set(v for v in values if v >= 0))
    for s in got:  # each step is exactly the rows of its index, with its channels
        rows = np.flatnonzero(np.asarray(values) == s.index)
        np.testing.assert_array_equal(s.recording.t, rec.t[rows])


@settings(max_examples=60, deadline=None)
@given(sizes=st.lists(st.integers(1, 40), max_size=30), seconds=st.floats(0.05, 1.5))
def test_a_timed_capture_does_not_depend_on_the_chunking(sizes, seconds):
    rec = Recording(np.arange(200) / RATE, np.ones((200, 3)), "m/s^2", {"theta": np.arange(200.0)})
    results = []
    for pieces in ([rec], cut(rec, sizes)):
        capture = StepCapture()
        capture.arm(seconds)
        results.append(as_tuples([s for chunk in pieces for s in capture.feed(chunk)] + capture.finish()))
    assert results[0] == results[1]
    (index, t, _, theta), = results[0]
    assert index is None and t[0] == 0 and t[-1] <= seconds < t[-1] + 1.5 / RATE and theta == list(range(len(t)))


def test_unarmed_capture_only_watches_and_a_capture_until_the_end_takes_the_rest():
    rec = Recording(np.arange(50) / RATE, np.zeros((50, 3)))
    capture = StepCapture()
    assert capture.feed(rec.slice(0, 20)) == [] and capture.progress is None
    capture.arm(None)
    assert capture.feed(rec.slice(20, 50)) == []
    (step,) = capture.finish()
    assert step.recording.t[0] == rec.t[20] and len(step.recording) == 30


def test_the_end_of_a_timed_capture_is_not_a_step():
    rec = Recording(np.arange(50) / RATE, np.zeros((50, 3)))
    capture = StepCapture()
    capture.arm(1.0)
    assert capture.feed(rec) == [] and capture.progress == pytest.approx(0.49)
    assert capture.finish() == [] and not capture.armed


def test_a_step_index_seen_twice_is_refused_and_a_marked_source_ignores_arming():
    capture = StepCapture(where="run.csv")
    capture.arm(None)  # a file: the whole of it, unless it marks its steps
    with pytest.raises(DataError, match=r"run.csv: step 1 \(step column value 0\) is not one contiguous block"):
        capture.feed(stream([0, 0, -1, 1, 1, 0, 0, -1]))
    # numbered from 1 like every other message (the column's value only beside it), whichever step repeats
    capture = StepCapture(where="run.csv")
    with pytest.raises(DataError, match=r"run.csv: step 3 \(step column value 2\) is not one contiguous block"):
        capture.feed(stream([0, -1, 1, -1, 2, 2, -1, 2, -1]))
    capture = StepCapture()
    capture.feed(stream([-1, 0]))
    with pytest.raises(DataError, match="marks its steps"):
        capture.arm(1.0)
