"""accelrig devices: the installed drivers and the devices they can find."""

from __future__ import annotations

from accelrig.errors import AccelrigError


def register(sub, groups) -> None:
    p = sub.add_parser("devices", description="List the installed drivers and the devices each can find now; "
                       "with --verbose, also every driver's URL options and each simulated rig's own.")
    p.add_argument("--verbose", "-v", action="store_true",
                   help="also list every driver's URL options, and each simulated rig's own options")
    p.set_defaults(func=run)


def run(args) -> int:
    from accelrig.acquisition.driver import load_drivers

    drivers = load_drivers()
    for scheme in sorted(drivers):
        cls = drivers[scheme]
        extra = f"  [extra: {cls.extra}]" if cls.extra else ""
        print(f"{scheme}://  {cls.description}{extra}")
        try:
            found = cls.discover()
        except AccelrigError as exc:
            print(f"    (cannot search: {exc})")
            found = []
        for url in found:
            print(f"    {url}")
        if args.verbose:
            options = cls.option_help()
            rigs = " and the options of the rig it names (listed under sim://)" if cls.takes_rig_options else ""
            if options:
                print(f"    {scheme}:// options{rigs}:")
            for option, help_text in options.items():
                print(f"        {option}: {help_text}")
            if scheme == "sim":
                _print_rigs()
    return 0


def _print_rigs() -> None:
    from accelrig.sim.rigs import RIGS

    for name in sorted(RIGS):
        rig = RIGS[name]
        print(f"    sim://{name}: {rig.description}")
        for option, help_text in rig.options.items():
            print(f"        {option}: {help_text}")
