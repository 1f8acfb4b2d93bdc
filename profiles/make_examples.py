"""Regenerate profiles/schema-v1.json (and the daemon's daemon-config-v1.json) and the example profiles, from the simulator (never by hand).

    python profiles/make_examples.py                 schema + every example whose method is installed
    python profiles/make_examples.py --schema-only   just the JSON Schemas
    python profiles/make_examples.py --strict        fail when a method is missing

Each calibration method (procedure + estimator) is one function: record its simulated rig through the
sim:// driver (the same path as `accelrig record`), calibrate with the
method's own entry point, and keep the result as a profile.  The noise
section comes from a still recording of the same simulated sensor (the sim
draws the sensor from the seed, whatever the rig).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.recorder import record
from accelrig.daemon.config import json_schema_text as daemon_schema_text
from accelrig.estimation.allan import noise_figures
from accelrig.profiles import profile_from_result, save_profile
from accelrig.profiles.io import utc_now
from accelrig.profiles.schema import json_schema_text
from accelrig.recording import Recording

HERE = Path(__file__).resolve().parent


def record_sim(url: str) -> Recording:
    with driver_for(url) as driver:
        return record(driver)


def example_static_faces_vp(seed: int):
    from accelrig.procedures.static.procedure import calibrate_static

    rec = record_sim(f"sim://static?seed={seed}&pace=fast")
    return calibrate_static(rec, method="vp"), rec


def example_static_faces_paper(seed: int):
    from accelrig.procedures.static.procedure import calibrate_static

    rec = record_sim(f"sim://static?seed={seed}&pace=fast")
    return calibrate_static(rec, model="paper", method="paper"), rec


def example_wheel_joint(seed: int):
    from accelrig.procedures.wheel.procedure import calibrate_wheel

    rec = record_sim(f"sim://wheel?seed={seed}&pace=fast")
    return calibrate_wheel(rec, radius=0.28, method="joint"), rec   # the rig's radius, measured as the paper advises


def example_wheel_paper(seed: int):
    from accelrig.procedures.wheel.procedure import calibrate_wheel

    rec = record_sim(f"sim://wheel?seed={seed}&pace=fast")
    return calibrate_wheel(rec, radius=0.28, method="paper"), rec


# example name -> (procedure module, function, seed): one per calibration method.  The rotary bench
# and the slider-crank verify a sensitivity or a rig; they produce no canonical correction, so no profile.
EXAMPLES = {
    "static_faces-vp": ("accelrig.procedures.static.procedure", example_static_faces_vp, 11),
    "static_faces-paper": ("accelrig.procedures.static.procedure", example_static_faces_paper, 11),
    "wheel-joint": ("accelrig.procedures.wheel.procedure", example_wheel_joint, 12),
    "wheel-paper": ("accelrig.procedures.wheel.procedure", example_wheel_paper, 12),
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
    (HERE / "daemon-config-v1.json").write_text(daemon_schema_text())
    print(f"wrote {HERE / 'daemon-config-v1.json'}")
    if args.schema_only:
        return 0
    missing = []
    for name, (module, make, seed) in EXAMPLES.items():
        if importlib.util.find_spec(module) is None:
            missing.append(name)
            print(f"skipped {name}: {module} is not installed", file=sys.stderr)
            continue
        result, rec = make(seed)
        profile = profile_from_result(result, rec)
        profile.data["noise"] = still_noise(seed)
        path = HERE / f"example-{name}.yaml"
        save_profile(profile, path)
        print(f"wrote {path}")
    if missing:
        print(f"missing examples: {', '.join(missing)}", file=sys.stderr)
        return 1 if args.strict else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
