"""A link that is down when a recording ends: the time from the last sample to the end is a gap, counted and said."""

from __future__ import annotations

import asyncio

import pytest

from accelrig.acquisition.url import DeviceURL
from accelrig.cli import main
from accelrig.recording import load_recording
from accelrig.sim.firmware import SimBleClient


def _trailing_gap(rec):
    gaps = rec.meta["gaps"]
    assert gaps and gaps[-1]["index"] == len(rec), gaps   # after the last sample
    return gaps[-1]


@pytest.mark.parametrize("url, cause", [
    # the BLE device drops at 1 s and is back only after the 6 s asked for ended (in device time)
    ("ble-sim://still?pace=fast&disconnect_at=1&outage=10", "disconnected: the link went down"),
    # the serial device stalls at 1 s for longer than the recording
    ("serial-sim://still?pace=fast&stall_at=1&stall_for=10", "frames lost on the link"),
])
def test_an_outage_running_past_the_end_asked_for_is_counted_and_said(tmp_path, capsys, url, cause):
    out = tmp_path / "o.csv"
    assert main(["record", url, "--seconds", "6", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "no samples lost" not in err
    assert "no sample came in the last 5." in err and "more than 1%" in err, err
    rec = load_recording(out)
    gap = _trailing_gap(rec)
    assert gap["missing"] == -1 and gap["cause"].startswith(cause)
    # the recording and its gap span the 6 s asked for
    assert rec.t[-1] - rec.t[0] + gap["seconds"] + 1 / rec.meta["nominal_rate"] == pytest.approx(6.0, abs=2e-3)


def test_a_link_still_reconnecting_when_the_time_asked_for_passes_ends_the_recording_with_that_gap(tmp_path, capsys):
    # real-time pace: the device is out of reach for 60 s from 0.4 s; the record ends at 1.5 s on the host's clock
    out = tmp_path / "o.csv"
    assert main(["record", "ble-sim://still?disconnect_at=0.4&outage=60&rate=200", "--seconds", "1.5",
                 "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "(disconnected: link down, reconnecting)" in err, err
    rec = load_recording(out)
    gap = _trailing_gap(rec)
    assert gap["cause"] == "disconnected: link down, reconnecting"
    assert rec.t[-1] - rec.t[0] + gap["seconds"] + 1 / 200 == pytest.approx(1.5, abs=0.02)


def test_the_simulated_ble_device_is_out_of_reach_for_its_outage_at_real_time_pace():
    from accelrig_drivers.serial import firmware_from_url

    firmware, _ = firmware_from_url(DeviceURL.parse("ble-sim://still"), 37)
    firmware.faults.outage = 30.0
    client = SimBleClient(firmware, "sim", pace="realtime")
    asyncio.run(client.connect())
    asyncio.run(client._drop_connection(client._now()))
    with pytest.raises(OSError, match="not reachable"):
        asyncio.run(client.connect())
    client.shared["t0"] -= 31.0          # 31 s of device time later
    assert asyncio.run(client.connect()) is True
