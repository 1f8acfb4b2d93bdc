"""Apply a profile's correction: to recordings, and in the acquisition path to ring-buffer chunks.

The correction is only valid for the device, range and units it was made
for (the profile records them).  ``check_compatible`` refuses anything else
unless forced; a forced or unverifiable application comes back as warnings
for the caller to show.  Every calibrated sample can carry its standard
uncertainty from the correction's covariance (Correction.sample_covariances,
applied in bounded chunks here for streams).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from accelrig.acquisition.ringbuffer import Chunk, Reader
from accelrig.errors import ProfileError
from accelrig.profiles.io import Profile
from accelrig.recording import Recording
from accelrig.result import Correction

UNCERTAINTY_CHANNELS = ("u_ax", "u_ay", "u_az")
# what the daemon writes beside the raw counts when its output is calibrated (daemon.device): applying a
# profile to its segments calibrates the raw counts again, so these are left out of the result (and said)
RECORDED_CALIBRATED_CHANNELS = ("cal_x", "cal_y", "cal_z")
RECORDED_UNCERTAINTY_CHANNELS = ("u_x", "u_y", "u_z")


def _same(a: float, b: float) -> bool:
    return abs(float(a) - float(b)) <= 1e-9 * max(abs(float(a)), abs(float(b)))


CLI_FORCE_HINT = "pass --force to use it anyway"


def check_compatible(profile: Profile, meta: dict, units: str, force: bool = False,
                     force_hint: str = CLI_FORCE_HINT) -> list[str]:
    """Refuse data from another device, chip, range or unit (ProfileError) unless ``force``.

    The one check of a profile against a device: applying, verifying and
    flashing (profiles.flash.plan_flash) all go through it, so ``--force`` means
    the same everywhere.

    ``meta`` is a recording's metadata or a DeviceInfo.to_dict(); ``units`` the
    units the data are in.  Returns warnings: what could not be checked, and
    what ``force`` let through.  ``force_hint`` says how to force where the
    refusal is shown (the command line's ``--force`` by default; the TUI's
    force field, or nothing where there is none).
    """
    problems: list[str] = []
    warnings: list[str] = []
    dev = profile.device
    who = f"profile {profile.path}" if profile.path else "the profile"
    data_id = meta.get("identity")
    if dev["identity"] is not None and data_id not in (None, "") and str(data_id) != dev["identity"]:
        problems.append(f"{who} is for device {dev['identity']!r}, not {str(data_id)!r}")
    elif dev["identity"] is None or data_id in (None, ""):
        unnamed = ("neither the profile nor the data name" if dev["identity"] is None and data_id in (None, "")
                   else "the profile does not name" if dev["identity"] is None else "the data do not name")
        warnings.append(f"cannot check the profile belongs to this device: {unnamed} the device")
    data_chip = meta.get("chip")
    if dev.get("chip") and data_chip and str(data_chip).lower() != str(dev["chip"]).lower():
        problems.append(f"{who} is for chip {dev['chip']!r}, not {str(data_chip)!r}")
    elif dev.get("who_am_i") is not None and meta.get("who_am_i") is not None and int(meta["who_am_i"]) != dev["who_am_i"]:
        problems.append(f"{who} is for WHO_AM_I 0x{dev['who_am_i']:02x} but the device answers 0x{int(meta['who_am_i']):02x}")
    if dev["range_g"] is not None and meta.get("range_g") is not None and not _same(dev["range_g"], meta["range_g"]):
        problems.append(f"{who} is for the +-{dev['range_g']:g} g range but the data were taken at +-{float(meta['range_g']):g} g")
    elif dev["scale"] is not None and meta.get("scale") is not None and not _same(dev["scale"], meta["scale"]):
        problems.append(f"{who} is for {dev['scale']:.6g} m/s^2 per count but the data use {float(meta['scale']):.6g}")
    if units not in (profile.units, "counts"):
        problems.append(f"the data are in {units} but {who} applies to raw {profile.units} (counts x nominal scale)")
    if problems:
        if not force:
            # every problem named: the person decides on --force knowing all of them
            raise ProfileError("; ".join(problems), force_hint)
        warnings.extend(f"forced: {p}" for p in problems)
    return warnings


def correction_for(profile: Profile, meta: dict | None) -> Correction:
    """The profile's correction for data from a device that already removes part of the bias.

    A profile always holds the correction of the sensor as it powers up
    (factory trim).  A chip whose offset registers were flashed subtracts
    ``meta['hardware_bias_removed']`` (m/s^2, raw frame) before the data leave
    it, so on its data the host must subtract only what is left:
    C (raw_hw - (b - removed)).  Subtracting b again would remove it twice.
    """
    corr = profile.correction
    removed = (meta or {}).get("hardware_bias_removed")
    if removed is None:
        return corr
    return Correction(corr.matrix, corr.bias - np.asarray(removed, dtype=float), corr.covariance)


def raw_si(rec: Recording, profile: Profile) -> np.ndarray:
    """The recording's samples as raw m/s^2 (counts x nominal scale), what the correction takes.

    Counts without a scale of their own take the profile's (same device, checked).
    """
    if rec.units == "counts" and not rec.meta.get("scale"):
        if profile.device["scale"] is None:
            raise ProfileError("the data are in counts and neither they nor the profile give the scale",
                               "convert the data to m/s^2 or record the range")
        rec = Recording(rec.t, rec.acc, rec.units, rec.channels, {**rec.meta, "scale": profile.device["scale"]})
    return rec.to_si().acc


def sample_uncertainty(correction: Correction, raw: np.ndarray, chunk: int = 65536) -> np.ndarray:
    """(n, 3) standard uncertainty of each calibrated axis, in bounded memory."""
    raw = np.asarray(raw, dtype=float).reshape(-1, 3)
    out = np.empty_like(raw)
    for start in range(0, raw.shape[0], chunk):
        cov = correction.sample_covariances(raw[start:start + chunk])
        out[start:start + chunk] = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
    return out


def apply_profile(
    profile: Profile, rec: Recording, force: bool = False, uncertainty: bool = False
) -> tuple[Recording, list[str]]:
    """Calibrated copy of ``rec`` (m/s^2) and the warnings to show.

    With ``uncertainty`` the standard uncertainty of each calibrated axis is
    added as channels u_ax, u_ay, u_az.
    """
    if "calibrated_with" in rec.meta:
        raise ProfileError("the recording is already calibrated (its metadata name a profile)",
                           "apply the profile to the raw recording")
    warnings = check_compatible(profile, rec.meta, rec.units, force)
    raw = raw_si(rec, profile)
    corr = correction_for(profile, rec.meta)
    channels = dict(rec.channels)
    recorded = [c for c in RECORDED_CALIBRATED_CHANNELS + RECORDED_UNCERTAINTY_CHANNELS if c in channels]
    if recorded:
        # calibrated while recorded (a daemon's calibrated output): ax, ay, az become the raw counts calibrated
        # with this profile; the recorded copies would repeat them (same profile) or contradict them (another)
        for name in recorded:
            del channels[name]
        ref = rec.meta.get("profile") if isinstance(rec.meta.get("profile"), dict) else {}
        used = ref.get("path")
        same = bool(ref) and (ref.get("identity"), ref.get("created"), ref.get("procedure"), ref.get("method")) == (
            profile.identity, profile.data["provenance"]["created"], profile.procedure, profile.method)
        warnings.append(
            f"the recording held channels {', '.join(recorded)}, calibrated while it was recorded"
            + (f" with profile {used}" if used else "")
            + "; they are left out: ax, ay, az are its raw counts calibrated with "
            + ("that same profile, and equal its cal_x, cal_y, cal_z" if same else f"profile {profile.path or '(given)'}")
            + ("; u_ax, u_ay, u_az are their uncertainties" if uncertainty else ""))
    if uncertainty:
        clash = [c for c in UNCERTAINTY_CHANNELS if c in channels]
        if clash:
            raise ProfileError(f"the recording already has channel(s) {', '.join(clash)}",
                               "it looks calibrated already; apply the profile to the raw recording")
        u = sample_uncertainty(corr, raw)
        channels.update({name: u[:, i] for i, name in enumerate(UNCERTAINTY_CHANNELS)})
    meta = dict(rec.meta)
    meta["units"] = "m/s^2"
    meta["calibrated_with"] = {
        "profile": str(profile.path) if profile.path else None,
        "identity": profile.identity,
        "created": profile.data["provenance"]["created"],
        "procedure": profile.procedure,
        "method": profile.method,
    }
    if warnings:
        meta["calibration_warnings"] = list(warnings)
    return Recording(rec.t, corr.apply(raw), "m/s^2", channels, meta), warnings


# ------------------------------------------------------------------ acquisition path


@dataclass
class CalibratedChunk:
    """A ring-buffer chunk with calibrated samples.

    acc          calibrated m/s^2 (n, 3)
    uncertainty  standard uncertainty of each calibrated axis from the correction (n, 3),
                 or None when not asked for
    chunk        the raw chunk (times, gaps, lost samples, channels)
    """

    acc: np.ndarray
    uncertainty: np.ndarray | None
    chunk: Chunk

    @property
    def t(self) -> np.ndarray:
        return self.chunk.t

    @property
    def n(self) -> int:
        return self.chunk.n


def calibrated(chunk: Chunk, profile: Profile, uncertainty: bool = False, force: bool = False,
               device: dict | None = None) -> CalibratedChunk:
    """Calibrate one chunk from a ring-buffer reader.

    ``device`` (DeviceInfo.to_dict(), or its ``extra``) tells whether the device
    removes part of the bias in hardware (flashed offsets): see correction_for.
    """
    check_compatible(profile, {"scale": chunk.scale}, "counts", force)
    corr = correction_for(profile, device)
    raw = chunk.acceleration()
    return CalibratedChunk(corr.apply(raw), sample_uncertainty(corr, raw) if uncertainty else None, chunk)


class CalibratedReader:
    """Wraps a ring-buffer Reader so that reads return calibrated samples.

    The device (a DeviceInfo or its dict) is checked against the profile once,
    at construction; the count scale of every chunk is checked as it arrives
    (a range change mid-stream must not be calibrated with the old profile).
    """

    def __init__(self, reader: Reader, profile: Profile, device=None, uncertainty: bool = False,
                 force: bool = False):
        self.reader = reader
        self.profile = profile
        self.uncertainty = uncertainty
        self.force = force
        info = device.to_dict() if hasattr(device, "to_dict") else dict(device or {})
        info.setdefault("scale", reader.buffer.scale)
        self.warnings = check_compatible(profile, info, "counts", force)
        self.device = {"hardware_bias_removed": (info.get("extra") or {}).get("hardware_bias_removed")}

    @property
    def pending(self) -> int:
        return self.reader.pending

    def read(self, max_samples: int | None = None) -> CalibratedChunk:
        return calibrated(self.reader.read(max_samples), self.profile, self.uncertainty, self.force, self.device)
