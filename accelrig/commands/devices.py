"""accelrig devices: the installed drivers and the devices they can find."""

from __future__ import annotations

from accelrig.errors import AccelrigError


def register(sub, groups) -> None:
    p = sub.add_parser("devices")
    p.add_argument("--verbose", "-v", action="store_true", help="also list the simulator's options (every rig's, and each rig's own)")
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
            continue
        for url in found:
            print(f"    {url}")
        if args.verbose and scheme == "sim":
            from accelrig.sim.rigs import RIGS

            print("    sim:// options of every rig:")
            for option, help_text in cls.sensor_options.items():
                print(f"        {option}: {help_text}")
            for name in sorted(RIGS):
                rig = RIGS[name]
                print(f"    sim://{name}: {rig.description}")
                for option, help_text in rig.options.items():
                    print(f"        {option}: {help_text}")
    return 0
