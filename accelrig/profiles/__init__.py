"""Device profiles: what a device keeps after calibration (schema v1 YAML), and how it is used again.

    profile_from_result(result, recording=None, device=None) -> Profile
    save_profile(profile, path, overwrite=True)   validates, writes atomically
    load_profile(path) -> Profile                  safe YAML, validated, one-line errors

The schema lives in accelrig/profiles/schema.py and is published as
profiles/schema-v1.json.
"""

from accelrig.profiles.io import Profile, load_profile, parse_profile_text, profile_from_result, save_profile
from accelrig.profiles.schema import SCHEMA_VERSION, json_schema, validate

__all__ = [
    "Profile",
    "SCHEMA_VERSION",
    "json_schema",
    "load_profile",
    "parse_profile_text",
    "profile_from_result",
    "save_profile",
    "validate",
]
