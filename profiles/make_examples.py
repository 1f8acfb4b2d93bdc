"""Regenerate profiles/schema-v1.json and the example profiles, from the simulator (never by hand).

    python profiles/make_examples.py                 schema + every example whose method is installed
    python profiles/make_examples.py --schema-only   just the JSON Schema
    python profiles/make_examples.py --strict        fail when a method is missing

Each calibration method is one function: record its simulated rig through the
sim:// driver (the same path as `accelrig record`), calibrate with the
method's own entry point, and keep the result as a profile.  The noise
section comes from a still recording of the same simulated sensor (the sim
draws the sensor from the seed, whatever the rig).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.recorder import record
from accelrig.estimation.allan import noise_figures
from accelrig.profiles import profile_from_result, save_profile
from accelrig.profiles.io import utc_now
from accelrig.profiles.schema import json_schema_text
from accelrig.recording import Recording

HERE = Path(__file__).resolve().parent


def record_sim(url: str) -> Recording:
    with driver_for(url) as driver:
        return record(driver)


def example_static_faces(seed: int):
    from accelrig.procedures.static_faces import calibrate_static

    rec = record_sim(f"sim://static?seed={seed}&pace=fast")
    return calibrate_static(rec), rec


def example_wheel(seed: int):
    from accelrig.procedures.wheel import calibrate_wheel

    rec = record_sim(f"sim://wheel?seed={seed}&pace=fast")
    return calibrate_wheel(rec, radius=0.28), rec   # the rig's radius, measured as the paper advises


def example_rotary_bench(seed: int):
    from accelrig.procedures.rotary_bench import calibrate_rotary   # noqa: F401  (the method's entry point)

    rec = record_sim(f"sim://rotary?seed={seed}&pace=fast")
    return calibrate_rotary(rec), rec


# method -> (function, seed).  Slider-crank is a verification, not a calibration: it keeps no correction.
EXAMPLES = {
    "static_faces": (example_static_faces, 11),
    "wheel": (example_wheel, 12),
    "rotary_bench": (example_rotary_bench, 13),
}


def still_noise(seed: int) -> dict:
    rec = record_sim(f"sim://still?seed={seed}&pace=fast&seconds=300")
    return noise_figures(rec).to_profile_dict(utc_now())


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--schema-only", action="store_true", help="only write profiles/schema-v1.json")
    parser.add_argument("--strict", action="store_true", help="exit non-zero when a method is not installed")
    args = parser.parse_args(argv)
    (HERE / "schema-v1.json").write_text(json_schema_text())
    print(f"wrote {HERE / 'schema-v1.json'}")
    if args.schema_only:
        return 0
    missing = []
    for method, (make, seed) in EXAMPLES.items():
        try:
            result, rec = make(seed)
        except ImportError as exc:
            missing.append(method)
            print(f"skipped {method}: its procedure is not installed ({exc})", file=sys.stderr)
            continue
        profile = profile_from_result(result, rec)
        profile.data["noise"] = still_noise(seed)
        path = HERE / f"example-{method}.yaml"
        save_profile(profile, path)
        print(f"wrote {path}")
    if missing:
        print(f"missing examples: {', '.join(missing)}", file=sys.stderr)
        return 1 if args.strict else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
