"""Prometheus metrics on localhost (``metrics_port``), the convention for headless services.

Optional: needs prometheus-client (``pip install 'accelrig[metrics]'``).  The
collector reads the same snapshot as the status socket at every scrape, so the
figures are never stale and nothing is counted twice.
"""

from __future__ import annotations

from collections.abc import Callable

from accelrig.daemon.device import RECORDING_STATES
from accelrig.errors import require_extra

COUNTERS = (
    ("accelrig_samples_delivered", "delivered", "samples the driver delivered"),
    ("accelrig_samples_written", "written", "samples written to segments"),
    ("accelrig_samples_dropped", "dropped", "samples delivered but not written (disk full), each in a gap record"),
    ("accelrig_samples_missing", "missing", "samples the device reported lost (FIFO overflow, lost frames)"),
    ("accelrig_gaps", "gaps", "gap records written"),
    ("accelrig_bytes_written", "bytes_written", "bytes of segments written"),
    ("accelrig_connects", "connects", "successful connections"),
)
# A device's MQTT publishing (the daemon's mqtt: section), from Publisher.stats(): counters, then gauges.
MQTT_COUNTERS = (
    ("accelrig_mqtt_messages_sent", "published", "data messages handed to the broker (QoS 1)"),
    ("accelrig_mqtt_messages_acknowledged", "acknowledged", "data messages the broker acknowledged"),
    ("accelrig_mqtt_dropped_samples", "dropped_samples",
     "samples dropped from a full spool, each in a gap record the collector receives"),
    ("accelrig_mqtt_dropped_messages", "dropped_messages", "spooled messages dropped (full spool)"),
    ("accelrig_mqtt_spool_gaps", "spool_gaps", "gap records made by a full spool"),
    ("accelrig_mqtt_reconnects", "reconnects", "connections to the broker after the first"),
)
MQTT_GAUGES = (
    ("accelrig_mqtt_spooled_messages", "spooled", "messages on disk waiting for the broker"),
    ("accelrig_mqtt_spool_bytes", "spool_bytes", "bytes of the spool on disk"),
)


def serve_metrics(port: int, snapshot: Callable[[], dict]):
    """Serve the metrics on 127.0.0.1:``port``; returns the server (``shutdown()`` stops it)."""
    from accelrig.daemon.config import ConfigError

    prometheus_client = require_extra("prometheus_client", "metrics_port", "prometheus-client", "metrics")
    from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily

    class Collector:
        def collect(self):
            devices = snapshot()["devices"]
            for name, key, text in COUNTERS:
                family = CounterMetricFamily(name, text, labels=["device"])
                for d in devices:
                    family.add_metric([d["name"]], d[key])
                yield family
            rate = GaugeMetricFamily("accelrig_delivered_rate_hz", "samples delivered per second, recent",
                                     labels=["device"])
            up = GaugeMetricFamily("accelrig_device_up", "1 while the device is recording (state streaming, or "
                                   "recording raw: without the profile it needs)", labels=["device", "state"])
            for d in devices:
                rate.add_metric([d["name"]], d["delivered_rate"] or 0.0)
                up.add_metric([d["name"], d["state"]], 1.0 if d["state"] in RECORDING_STATES else 0.0)
            yield rate
            yield up
            publishing = [d for d in devices if d.get("mqtt")]
            if not publishing:
                return
            for name, key, text in MQTT_COUNTERS:
                family = CounterMetricFamily(name, text, labels=["device"])
                for d in publishing:
                    family.add_metric([d["name"]], d["mqtt"].get(key) or 0)
                yield family
            for name, key, text in MQTT_GAUGES:
                family = GaugeMetricFamily(name, text, labels=["device"])
                for d in publishing:
                    family.add_metric([d["name"]], d["mqtt"].get(key) or 0)
                yield family
            connected = GaugeMetricFamily("accelrig_mqtt_connected", "1 while connected to the broker",
                                          labels=["device"])
            for d in publishing:
                connected.add_metric([d["name"]], 1.0 if d["mqtt"].get("connected") else 0.0)
            yield connected

    registry = prometheus_client.CollectorRegistry()
    registry.register(Collector())
    try:
        server, _thread = prometheus_client.start_http_server(port, addr="127.0.0.1", registry=registry)
    except OSError as exc:
        raise ConfigError(f"metrics_port: cannot listen on 127.0.0.1:{port} ({exc.strerror})",
                          "choose a free port, or remove metrics_port") from None
    return server
