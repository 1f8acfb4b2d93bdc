"""accelrig tui [--device URL]: the guided calibration interface."""

from __future__ import annotations

from accelrig.errors import require_extra


def register(sub, groups) -> None:
    p = sub.add_parser(
        "tui",
        description="Open the terminal interface. With no --device it opens on a simulated static rig, "
        "so it works without hardware.",
    )
    p.add_argument("--device", default=None,
                   help="device URL to open first (default: sim://static, a simulated device)")
    p.add_argument("--profile-dir", default=None,
                   help="directory the wizards offer for saving profiles, captures and reports (default: profiles "
                   "into the profile store, $ACCELRIG_HOME/profiles; captures and reports beside it)")
    p.set_defaults(func=run)


def run(args) -> int:
    require_extra("textual", "the TUI", "textual", "tui")  # says which extra is missing
    from accelrig.tui.app import DEFAULT_DEVICE, AccelrigApp

    app = AccelrigApp(device=args.device or DEFAULT_DEVICE, profile_dir=args.profile_dir)
    app.run()
    return int(app.return_code or 0)
