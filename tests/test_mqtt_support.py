"""The test broker (mqtt_support.Broker) starts on ports of its own even when another process takes the one
free_port() chose before mosquitto binds it (two pytest workers, or any outgoing connection)."""

import shutil
import socket

import pytest

import mqtt_support

if shutil.which("mosquitto") is None:
    pytest.skip("mosquitto is not installed (CI installs it: apt-get install mosquitto)", allow_module_level=True)


def test_a_port_taken_before_mosquitto_binds_it_gives_the_broker_another_and_a_restart_keeps_it(tmp_path,
                                                                                               monkeypatch):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        chosen = iter([port])   # free_port's first answer is taken by the time mosquitto starts
        real_free_port = mqtt_support.free_port
        monkeypatch.setattr(mqtt_support, "free_port", lambda: next(chosen, None) or real_free_port())
        (tmp_path / "broker").mkdir()
        broker = mqtt_support.Broker(tmp_path / "broker")
        assert broker.port == port
        try:
            broker.start()
            assert broker.port != port and broker.proc.poll() is None
            assert f"port {broker.port}" in broker.log()
            socket.create_connection(("127.0.0.1", broker.port), 2).close()
            first = broker.port
            broker.stop()
            broker.start()   # the clients know this port: a restart keeps it
            assert broker.port == first and broker.proc.poll() is None
        finally:
            broker.stop()


def test_the_fleet_benchmark_takes_its_port_from_the_one_free_port():
    """bench_fleet.py had its own copy of the old free_port (any ephemeral port, which an outgoing connection
    may be given meanwhile): it uses mqtt_support's."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).parent / "benchmarks" / "bench_fleet.py"
    spec = importlib.util.spec_from_file_location("bench_fleet_under_test", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.free_port is mqtt_support.free_port
