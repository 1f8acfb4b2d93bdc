"""Where a calibration command puts the profile it makes: one policy for every command (and the TUI).

By default the profile goes into the profile store (accelrig.profiles.store), filed under the device's
identity, where ``accelrig profile``, the daemon and the TUI find it; ``-o FILE`` writes it to a file
instead; ``--no-store`` writes none.  The path is said on stderr, so ``--json`` output stays one object.
"""

from __future__ import annotations

import sys

# where the profile store is when --store is not given (accelrig.profiles.store.default_store_dir)
STORE_DEFAULT = "$ACCELRIG_HOME/profiles, else $XDG_DATA_HOME/accelrig/profiles, else ~/.local/share/accelrig/profiles"


def add_profile_arguments(parser, what: str = "the device profile (YAML)") -> None:
    parser.add_argument("-o", "--output", metavar="FILE", help=f"write {what} to FILE instead of the profile store")
    parser.add_argument("--store", metavar="DIR", help=f"profile store (default: {STORE_DEFAULT})")
    parser.add_argument("--no-store", action="store_true", help="write no profile")
    parser.add_argument("--force", action="store_true", help="replace the -o file if it exists")


def check_profile_target(args) -> None:
    """Refuse an -o the write would refuse (special file, the input itself, an existing file without
    --force) before any work is done."""
    if args.output:
        from accelrig.files import writable_target

        writable_target(args.output, args.force, inputs=[args.recording])


def write_profile(result, rec, args) -> str | None:
    """Save the profile of ``result`` as the arguments say; returns where (None: not written)."""
    if args.no_store and not args.output:
        return None
    # Imported here: the profiles package is optional for computing a calibration.
    from accelrig.errors import ProfileError
    from accelrig.profiles import ProfileStore, profile_from_result, save_profile

    profile = profile_from_result(result, rec)
    if args.output:
        # validated and written atomically: nothing half-written
        save_profile(profile, args.output, overwrite=args.force, inputs=[args.recording])
        where = str(args.output)
    else:
        try:
            where = str(ProfileStore(args.store).add(profile))
        except ProfileError as exc:
            print(f"accelrig: no profile stored: {exc.message} (give -o FILE to keep it as a file)", file=sys.stderr)
            return None
    print(f"profile written to {where}", file=sys.stderr)
    return where
