"""A few seconds of fuzzing in every run: each parser ends in a result or an AccelrigError, nothing else.
Longer runs: tests/benchmarks/bench_fuzz.py."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings

from hostile.fuzz_targets import TARGETS


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_fuzz(name):
    target, strategy = TARGETS[name]

    @settings(max_examples=60 if name.startswith("YAML") else 120, deadline=None, database=None, derandomize=True,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(strategy)
    def run(data: bytes) -> None:
        target(data)

    run()
