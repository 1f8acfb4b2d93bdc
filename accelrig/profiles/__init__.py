"""Device profiles: what a device keeps after calibration (schema v1 YAML), and how it is used again.

    profile_from_result(result, recording=None, device=None) -> Profile
    save_profile(profile, path, overwrite=True)   validates, writes atomically
    load_profile(path) -> Profile                  safe YAML, validated, one-line errors
    ProfileStore                                   profiles per device identity (store.py)
    apply_profile, CalibratedReader                the correction on recordings and ring-buffer reads (apply.py)

The schema lives in accelrig/profiles/schema.py and is published as
profiles/schema-v1.json.
"""

from accelrig.profiles.apply import CalibratedReader, apply_profile, calibrated, check_compatible
from accelrig.profiles.io import Profile, load_profile, parse_profile_text, profile_from_result, save_profile
from accelrig.profiles.schema import SCHEMA_VERSION, json_schema, validate
from accelrig.profiles.store import ProfileStore

__all__ = [
    "CalibratedReader",
    "Profile",
    "ProfileStore",
    "apply_profile",
    "calibrated",
    "check_compatible",
    "SCHEMA_VERSION",
    "json_schema",
    "load_profile",
    "parse_profile_text",
    "profile_from_result",
    "save_profile",
    "validate",
]
