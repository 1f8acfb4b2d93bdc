"""Ring buffer: wrap-around, overflow accounting, gaps, concurrent producer/consumer."""

import dataclasses
import threading

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from accelrig.acquisition.block import Block
from accelrig.acquisition.ringbuffer import RingBuffer

SCALE = 0.001


def make_block(seq: int, first: int, n: int, gap: int = 0, channels=("theta",)) -> Block:
    idx = np.arange(first, first + n)
    counts = np.stack([idx % 30000, -(idx % 20000), idx % 7], axis=1).astype(np.int16)
    return Block(seq=seq, counter=first, host_time=0.0, counts=counts, scale=SCALE,
                 t=idx / 100.0, gap_before=gap, channels={c: idx * 0.5 for c in channels})


@settings(max_examples=150, deadline=None)
@given(
    capacity=st.integers(1, 64),
    sizes=st.lists(st.integers(1, 80), min_size=1, max_size=40),
    read_every=st.integers(1, 5),
)
def test_reader_sees_every_sample_or_counts_it_lost(capacity, sizes, read_every):
    """Wrap-around and overflow: delivered + lost == written, and what is delivered is exact."""
    buf = RingBuffer(capacity, SCALE, ("theta",))
    reader = buf.reader()
    written = 0
    delivered = []
    lost = 0
    for i, n in enumerate(sizes):
        buf.write(make_block(i, written, n))
        written += n
        if i % read_every == 0:
            chunk = reader.read()
            lost += chunk.lost
            delivered.append(np.arange(chunk.first_index, chunk.first_index + chunk.n))
            expected = make_block(0, chunk.first_index, chunk.n) if chunk.n else None
            if chunk.n:
                np.testing.assert_array_equal(chunk.counts, expected.counts)
                np.testing.assert_array_equal(chunk.t, expected.t)
                np.testing.assert_array_equal(chunk.channels["theta"], expected.channels["theta"])
    chunk = reader.read()
    lost += chunk.lost
    delivered.append(np.arange(chunk.first_index, chunk.first_index + chunk.n))
    got = np.concatenate(delivered)
    assert got.size + lost == written
    assert np.all(np.diff(got) == 1) or got.size == 0 or lost > 0
    assert np.unique(got).size == got.size  # nothing delivered twice
    assert got.size == 0 or got[-1] == written - 1  # the newest data always arrives
    assert reader.lost_total == lost


@settings(max_examples=100, deadline=None)
@given(
    capacity=st.integers(4, 50),
    blocks=st.lists(st.tuples(st.integers(0, 30), st.integers(0, 9)), min_size=1, max_size=30),
    read_pattern=st.lists(st.booleans(), min_size=30, max_size=30),
)
def test_every_driver_gap_reaches_every_reader(capacity, blocks, read_pattern):
    """Gaps survive to a fast reader, a slow reader and one that reads only at the end, each exactly once
    (an empty block's gap, at the head, included)."""
    buf = RingBuffer(capacity, SCALE, ("theta",))
    fast, sometimes, late = buf.reader(), buf.reader(), buf.reader()
    totals = {"fast": 0, "sometimes": 0, "late": 0}

    def account(name, chunk):
        totals[name] += sum(max(m, 0) for _, m, _ in chunk.gaps) + chunk.skipped_gap

    written = 0
    for i, (n, gap) in enumerate(blocks):
        buf.write(make_block(i, written, n, gap))
        written += n
        account("fast", fast.read())
        if read_pattern[i]:
            account("sometimes", sometimes.read())
    for name, reader in (("sometimes", sometimes), ("late", late), ("fast", fast)):
        account(name, reader.read())
    expected = sum(g for _, g in blocks)
    assert totals == {"fast": expected, "sometimes": expected, "late": expected}


def test_gap_positions_are_exact():
    buf = RingBuffer(100, SCALE, ("theta",))
    r = buf.reader()
    buf.write(make_block(0, 0, 10))
    buf.write(make_block(1, 15, 10, gap=5))
    buf.write(make_block(2, 25, 3, gap=-1))
    chunk = r.read()
    assert chunk.gaps == [(10, 5, None), (20, -1, None)]
    assert chunk.lost == 0 and chunk.skipped_gap == 0


def test_a_gap_after_the_last_sample_reaches_readers_at_once_with_its_cause():
    # a stream that ended with a loss: no sample will ever follow the gap to carry it
    buf = RingBuffer(100, SCALE, ("theta",))
    r = buf.reader()
    buf.write(make_block(0, 0, 10))
    assert r.read().gaps == []
    end = make_block(1, 14, 0, gap=4)
    buf.write(dataclasses.replace(end, gap_cause="dropped at the end"))
    assert r.read().gaps == [(0, 4, "dropped at the end")]
    assert r.read().gaps == [] and r.read().skipped_gap == 0   # once
    late = buf.reader(from_oldest=True).read()
    assert late.n == 10 and late.gaps == [(10, 4, "dropped at the end")]


def test_new_reader_from_oldest_and_from_now():
    buf = RingBuffer(8, SCALE, ("theta",))
    buf.write(make_block(0, 0, 12))
    assert buf.reader(from_oldest=True).read().first_index == 4
    late = buf.reader()
    assert late.read().n == 0


def test_block_larger_than_capacity_keeps_newest():
    buf = RingBuffer(5, SCALE, ("theta",))
    r = buf.reader()
    buf.write(make_block(0, 0, 12))
    chunk = r.read()
    assert chunk.lost == 7 and chunk.first_index == 7 and chunk.n == 5
    np.testing.assert_array_equal(chunk.t, np.arange(7, 12) / 100.0)


def test_memory_is_preallocated_and_flat():
    buf = RingBuffer(1000, SCALE, ("theta",))
    before = buf.nbytes
    r = buf.reader()
    for i in range(500):
        buf.write(make_block(i, i * 64, 64))
        if i % 3 == 0:
            r.read()
    assert buf.nbytes == before == 1000 * (6 + 8 + 8)


def test_concurrent_producer_and_consumers_never_see_torn_data():
    """A producer thread writes while two readers copy; every delivered sample is exact."""
    capacity = 256
    buf = RingBuffer(capacity, SCALE, ("theta",))
    n_blocks, block = 3000, 37
    stop = threading.Event()
    results = {}

    def consume(name, reader, max_samples):
        got, lost, bad = 0, 0, 0
        while True:
            done = stop.is_set()
            chunk = reader.read(max_samples)
            lost += chunk.lost
            if chunk.n:
                ref = make_block(0, chunk.first_index, chunk.n)
                bad += int(np.count_nonzero(chunk.counts != ref.counts) + np.count_nonzero(chunk.t != ref.t))
                got += chunk.n
            if done and reader.pending == 0:
                break
        results[name] = (got, lost, bad)

    threads = [threading.Thread(target=consume, args=("greedy", buf.reader(), None)),
               threading.Thread(target=consume, args=("sipping", buf.reader(), 50))]
    for th in threads:
        th.start()
    for i in range(n_blocks):
        buf.write(make_block(i, i * block, block))
    stop.set()
    for th in threads:
        th.join(timeout=60)
    total = n_blocks * block
    for name, (got, lost, bad) in results.items():
        assert bad == 0, name
        assert got + lost == total, name
