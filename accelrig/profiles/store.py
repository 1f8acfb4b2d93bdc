"""The profile store: profiles kept per device identity in the user's data directory.

Location: ``$ACCELRIG_HOME/profiles`` if ACCELRIG_HOME is set, else
``$XDG_DATA_HOME/accelrig/profiles``, else ``~/.local/share/accelrig/profiles``;
any command taking ``--store DIR`` overrides it.

Layout: one directory per device identity, named by a filesystem-safe form
of the identity plus a short hash of the exact identity (so 'AA:BB' and
'AA_BB' never share a directory), holding one file per calibration named by
its creation time and procedure:

    profiles/sim-still-3-1f2e3d4c/20261122T032500Z-static_faces.yaml

Choosing: the latest profile, or the one closest in time to a date (imucal's
idea); a warning when the chosen one is older than a configurable age.

A file that cannot be used (not valid YAML, not a valid profile, filed under
another device, a link out of the store) or a device folder that cannot be
read is skipped, never fatal: every other device, and the device's other
profiles, stay usable.  Each skipped entry is a warning naming it and why
(``Broken``), in ``profile list``, in the choice's warnings and in
``daemon check``: one half-copied file must not stop a fleet from recording.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path

from accelrig.errors import AccelrigError, DataError, ProfileError
from accelrig.files import OutputExists, accelrig_home, make_dirs
from accelrig.profiles.io import Profile, load_profile, save_profile
from accelrig.settings import Setting
from accelrig.spec import parse_datetime

DEFAULT_MAX_AGE_DAYS = 365.0


def default_store_dir() -> Path:
    return accelrig_home() / "profiles"


def device_key(identity: str) -> str:
    """Directory name for a device identity: safe characters + 8 hex of its sha256."""
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", identity).strip("._") or "device"
    digest = hashlib.sha256(identity.encode("utf-8")).hexdigest()[:8]
    return f"{safe[:60]}-{digest}"


def _sequence(path: Path) -> int:
    match = re.search(r"-(\d+)$", path.stem)
    return int(match.group(1)) if match else 1


@dataclass
class StoredProfile:
    path: Path
    profile: Profile

    @property
    def identity(self) -> str:
        return self.profile.identity

    @property
    def created(self) -> datetime:
        return self.profile.created


class UnusableProfiles(ProfileError):
    """The device has files in the store, but none can be used: the fix is to repair them, not to recalibrate."""


@dataclass
class Broken:
    """A store entry that cannot be used (skipped): its path and why."""

    path: Path
    reason: str   # names the path

    def warning(self) -> str:
        return (f"skipped a store entry that cannot be used: {self.reason}; repair or remove it "
                "(`accelrig profile validate FILE` says what is wrong)")

    @property
    def filed(self) -> datetime | None:
        """When the entry was filed, from the stamp its file name starts with (the store names files so);
        None for a folder or a name without one."""
        match = re.match(r"(\d{8}T\d{6}Z)", self.path.name)
        return datetime.strptime(match.group(1), "%Y%m%dT%H%M%SZ").replace(tzinfo=UTC) if match else None


@dataclass
class Choice:
    stored: StoredProfile
    warnings: list[str]
    notes: list[str] = field(default_factory=list)   # which profile was chosen among several, and why
    skipped: list[Broken] = field(default_factory=list)   # the device's files that could not be used
    chosen_as: str = ""   # the chosen profile in words and the rule that chose it, for whoever says which was used


class ProfileStore:
    def __init__(self, root: str | os.PathLike | None = None):
        self.root = Path(root) if root is not None else default_store_dir()

    def device_dir(self, identity: str) -> Path:
        return self.root / device_key(identity)

    def path_for(self, profile: Profile) -> Path:
        """Where ``add`` would keep ``profile`` now (the first name not taken yet), to show before saving."""
        for path in self._free_names(profile):
            return path
        raise ProfileError(f"{self.device_dir(profile.identity)}: 9999 profiles of the same second and procedure",
                           "is a script looping?")

    def _free_names(self, profile: Profile):
        """The names ``add`` tries for ``profile``, free ones only, in order (at most 9999 of one second)."""
        identity = profile.identity
        if identity is None:
            raise ProfileError(
                "the profile does not name its device (device.identity is null), so the store cannot file it",
                "set device.identity in the profile, or keep it as a file",
            )
        directory = self.device_dir(identity)
        self._check_inside(directory)
        stamp = profile.created.strftime("%Y%m%dT%H%M%SZ")
        base = f"{stamp}-{re.sub(r'[^A-Za-z0-9_-]+', '_', profile.procedure)}"
        for k in range(1, 10000):
            path = directory / (f"{base}.yaml" if k == 1 else f"{base}-{k}.yaml")
            if not (path.exists() or path.is_symlink()):
                yield path

    def add(self, profile: Profile) -> Path:
        """Keep a profile for its device; returns where.  Never overwrites an existing file.

        The name is claimed exclusively (files.atomic_write without overwrite), so two
        ``profile add`` of the same second both land, as -2, -3...  Folders are created 0755 and
        files 0644 less the umask: others read the store, nobody but its owner writes it.
        """
        first = self.path_for(profile)   # refuses a profile without identity or a link out of the store
        make_dirs(first.parent, 0o755)
        for path in self._free_names(profile):
            try:
                save_profile(profile, path, overwrite=False, mode=0o644)
            except OutputExists:
                continue   # taken by a concurrent add since we looked: try the next name
            return path
        raise ProfileError(f"{first.parent}: 9999 profiles of the same second and procedure", "is a script looping?")

    def _check_inside(self, path: Path) -> None:
        """Refuse a store entry that is a link leading out of the store (it would write or read elsewhere)."""
        root = Path(os.path.realpath(self.root))
        real = Path(os.path.realpath(path))
        if real != root and root not in real.parents:
            raise ProfileError(f"{path}: links outside the store (to {real}): refusing to follow it",
                               "replace the link by the folder or file itself")

    def _listing(self, folder: Path) -> list[Path]:
        """The entries of a store folder, sorted; an unreadable folder is an error naming it."""
        try:
            with os.scandir(folder) as it:
                return sorted(Path(e.path) for e in it)
        except OSError as exc:
            raise ProfileError(f"{folder}: cannot read the store folder ({exc.strerror})",
                               "fix its permissions") from None

    def scan(self, identity: str | None = None) -> tuple[list[StoredProfile], list[Broken]]:
        """Every valid stored profile (of one device if given), oldest first, and every entry skipped.

        A file that does not load or is filed under another device, a device folder that cannot be
        read, or a link out of the store is skipped and returned as ``Broken`` (path, why): the rest of
        the store stays usable.  Only a store root that cannot be read is an error.
        """
        if not self.root.is_dir():
            return [], []
        if identity is not None:
            dirs = [self.device_dir(identity)]
        else:
            dirs = [p for p in self._listing(self.root) if p.is_dir()]
        out, broken = [], []
        for d in dirs:
            if not d.is_dir():
                continue
            try:
                self._check_inside(d)
                listing = self._listing(d)
            except ProfileError as exc:
                broken.append(Broken(d, _reason(exc, d)))
                continue
            for path in listing:
                if path.suffix != ".yaml":
                    continue
                try:
                    self._check_inside(path)
                    profile = load_profile(path)
                except AccelrigError as exc:
                    broken.append(Broken(path, _reason(exc, path)))
                    continue
                if identity is not None and profile.identity != identity:
                    broken.append(Broken(path, f"{path}: device.identity {profile.identity!r} does not belong "
                                               f"in the folder of {identity!r} (move the file to its device's "
                                               "folder)"))
                    continue
                out.append(StoredProfile(path, profile))
        # Same creation second: the file added later (higher -N suffix) counts as newer.
        return sorted(out, key=lambda s: (s.created, _sequence(s.path))), broken

    def entries(self, identity: str | None = None) -> list[StoredProfile]:
        """Every valid stored profile (of one device if given), oldest first; unusable entries are skipped
        (``scan`` returns them too, to be said)."""
        return self.scan(identity)[0]

    def identities(self) -> list[str]:
        return sorted({s.identity for s in self.entries()})

    def choose(
        self,
        identity: str,
        date: str | datetime | None = None,
        max_age_days: float = DEFAULT_MAX_AGE_DAYS,
        now: datetime | None = None,
        data: dict | None = None,
        units: str = "counts",
    ) -> Choice:
        """The latest profile of a device, or the one closest in time to ``date``.

        With ``data`` (the metadata of the data the profile is for, in ``units``) only the profiles that
        apply to them count (``check_compatible``: chip, range, scale, units): a device calibrated on the
        wheel at +-4 g and statically at +-2 g gets the +-2 g profile for +-2 g data, whichever is newer.
        The notes say which was chosen and why the ones the rule would have preferred were passed over.
        When none applies, the rule's choice is returned as without ``data`` (its check then refuses,
        naming what differs)."""
        try:
            Setting("max_age_days", "", unit="days", low=0.0).parse(max_age_days)
        except DataError as exc:
            raise ProfileError(exc.message) from None
        if isinstance(date, str):
            try:
                parse_datetime(date)
            except ValueError:
                raise ProfileError(f"{date!r} is not a date", "give an ISO date, e.g. 2026-11-01") from None
        entries, skipped = self.scan(identity)
        if not entries and skipped:
            raise UnusableProfiles(f"no stored profile of device {identity!r} can be used: "
                                   + "; ".join(b.reason for b in skipped),
                                   "repair or remove " + ("that file" if len(skipped) == 1 else "those files")
                                   + " (`accelrig profile validate FILE` says what is wrong)")
        if not entries:
            known, broken = self.scan()
            names = sorted({s.identity for s in known})
            hint = (f"known devices: {', '.join(names)}" if names
                    else f"the store {self.root} is empty" if not broken
                    else f"the store {self.root} holds no usable profile")
            if broken:   # one of them may be this device's, misfiled or damaged
                hint += (f"; {len(broken)} store entr{'y' if len(broken) == 1 else 'ies'} cannot be used: "
                         + "; ".join(b.reason for b in broken))
            raise ProfileError(f"no stored profile for device {identity!r}", hint)
        if date is None:
            reference = now or datetime.now(UTC)
            order = entries[::-1]   # newest first
            rule = "the newest"
        else:
            reference = parse_datetime(date) if isinstance(date, str) else date.astimezone(UTC)
            order = sorted(entries, key=lambda s: (abs(s.created - reference), -s.created.timestamp()))
            rule = f"the closest to {reference.strftime('%Y-%m-%d %H:%M')} UTC"
        chosen, notes, why_not = order[0], [], {}
        if data is not None and len(entries) > 1:
            from accelrig.profiles.apply import check_compatible

            for stored in order:
                try:
                    check_compatible(stored.profile, data, units)
                except ProfileError as exc:
                    why_not[stored.path] = exc.message
                    continue
                chosen = stored
                break
            if chosen.path in why_not:
                notes.append(f"no stored profile of {identity!r} applies to the data ({len(entries)} stored)")
            elif why_not:
                notes.append(f"profile {chosen.path.name} ({_describe(chosen)}): {rule} that applies to the data")
                notes += [f"passed over {s.path.name} ({_describe(s)}): {why_not[s.path]}"
                          for s in order[:order.index(chosen)]]
        warnings = [b.warning() for b in skipped]
        # a damaged file newer than the one used: the data get an older calibration than the newest filed,
        # which the operator must hear as such, not as a store entry skipped in passing
        newer = [b for b in skipped if b.filed is not None and b.filed > chosen.created]
        if newer and date is None:
            warnings.insert(0, f"the newest profile filed for {identity!r} ({newer[-1].path.name}) cannot be read: "
                               f"an older one is used instead ({chosen.path.name}, {_describe(chosen)}); repair "
                               "or remove the damaged file, or file the newest calibration again")
        age = reference - chosen.created
        if age > timedelta(days=max_age_days):
            when = "now" if date is None else reference.strftime("%Y-%m-%d")
            warnings.append(
                f"profile {chosen.path.name} is {age.days} days older than {when} "
                f"(more than {max_age_days:g}); recalibrate the device"
            )
        chosen_as = (f"profile {chosen.path} ({_describe(chosen)}): {rule} of {len(entries)} stored for "
                     f"{identity!r}" + (" that applies to the data" if data is not None and chosen.path not in why_not
                                        else ""))
        return Choice(chosen, warnings, notes, skipped, chosen_as)


def _reason(exc: AccelrigError, path: Path) -> str:
    """Why an entry was skipped, naming it (load errors name their file already)."""
    text = str(exc)
    return text if str(path) in text else f"{path}: {text}"


def _describe(stored: StoredProfile) -> str:
    """A stored profile in a few words: procedure, range, date."""
    dev, parts = stored.profile.device, [stored.profile.procedure]
    if dev.get("range_g") is not None:
        parts.append(f"±{dev['range_g']:g} g")
    parts.append(stored.created.strftime("%Y-%m-%d %H:%M"))
    return ", ".join(parts)
