"""Still-pose detection for the six-face calibration: which face is down, held how long, and is it usable.

``PoseDetector`` takes the raw stream in pieces of any size and says what the
operator should be told as contract ``Event``s; the specific happening is in
``event.data``: ``kind`` (hold_still, already_done, captured, progress, again,
complete, too_short, moved, not_flat, saturated, redo), ``face`` and ``time``.

The guided sequence: the six faces in any order, then one face of each axis
again (``again``: a face held twice, far apart in time, is the only check of a
slow offset drift, ``noise.py`` says why, and each axis needs its own), then
the opposite faces once more (the second round): per axis the holds of both
faces then fix offset, gain and drift rate with a degree of freedom to spare,
so a drift that leaves the line between the holds can show (docs/static.md,
"What twelve holds cannot see"); then the first round's faces a third time,
at the end (the last round): a face seen at three times spread over the run
shows the drift's shape, not only its straight line (a thermal cycle that has
come back by the second hold).  Ending on the face held three times makes its
holds span most of the run (from its first hold, among the first five, to the
last) whatever the pace of the holds, which the shape test needs
(``noise.SHAPE_MIN_COVER``); held in the middle instead, the face first held
fifth spanned exactly half the run and lost its test in about half the runs.
Six faces are enough to compute (``faces_done``); the sequence is complete
with the three rounds (``again_rounds``).
Fed a whole recording or the same samples in chunks it finds the same poses.

Detection works on RAW data in m/s^2 (never on calibrated data: the
calibration does not exist yet, and a wrong one must not hide motion):

  dispersion  norm of the per-axis sample sd over a sliding window (0.2 s);
  hysteresis  still when it drops below ``still_threshold`` (0.25 m/s^2, the
              value PX4's detect_orientation uses), moving again only above
              ``motion_factor`` x that, so noise near the threshold does not chatter;
  edges       found from the data, not by a fixed trim: windows whose dispersion
              is above 1.5 x the pose's median hold motion and are dropped, and
              one window more at each end (the detector's resolution), and
              before a motion ``lift`` s (0.3: the slow start of a lift); then
              whole off-plateau blocks at either end (``moved`` below), then the
              first and last samples whose summed offset from the plateau is
              significant (``_edge_cuts``: the hand's lift starts as a slow tilt
              before the dispersion sees it); every other still sample is kept
              (``trim`` s more at both ends only if asked, default 0);
  hold        a pose counts once it has ``min_hold`` s of clean data; the live
              flow asks for ``hold`` s (default 4) before saying "captured";
  face        the nearest face (the axis with the largest |mean|; its sign names
              the face down, +z down: az ~ -g) and the angle from it, on the raw
              axes; every still pose is kept whatever the angle (the model decides:
              six-face mode refuses a pose far from a face, multi-position uses it);
              the live face grid counts a face done within ``face_tolerance_deg``;
  moved       means of 0.25 s blocks must agree with the pose's plateau within
              ``drift_tolerance`` (0.05 m/s^2, about 0.3 degrees of tilt) or 6
              noise sd, whichever is larger, the sd counting the slow noise's
              wander over the hold as the blocks' |a| shows it (a tip leaves
              |a| alone, ``MOVED_WANDER_SD``); up to ``settle`` s (1.0) off the
              plateau (by 4.5 sd of a block mean) at either end is the hand settling or starting to lift and
              is trimmed; a shift elsewhere (a slow tip that never trips the
              dispersion) means the pose moved;
  saturated   samples at the full scale of the sensor range, when known.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from accelrig.errors import CalibrationError, DataError
from accelrig.geometry import AXES, FACES, opposite_face
from accelrig.procedures.contract import Event
from accelrig.recording import count_scale
from accelrig.units import COUNT_MAX, STANDARD_GRAVITY, saturated

# Why the drift check's second and last rounds are asked for, in the operator's words (the wizard says them too)
OPPOSITE_ROUND_WHY = "so the fit can test the drift between the holds"
LAST_ROUND_WHY = "so their holds, spread over the run, show the drift's shape"
# The holds the guided sequence asks for: the six faces, then the drift check's three rounds of one per axis
DRIFT_HOLDS = 3 * len(AXES)   # the drift check: one face of each axis, its opposite, the first a third time
GUIDED_HOLDS = len(FACES) + DRIFT_HOLDS

_CHI2_1_MEDIAN = 0.4549364   # median of chi^2 with 1 dof: median(d^2) = 0.455 var(d) for a normal d
# A block mean off the plateau by this many sds of the blocks' |a| (which a rotation leaves unchanged) is a move
# however slowly the noise wanders (_settle).
MOVED_WANDER_SD = 10.0

# The detector's own kinds of happening, as the contract's kinds of event (data["kind"] keeps the own one).
EVENT_KIND = {
    "start": "instruction", "hold_still": "instruction", "already_done": "instruction", "redo": "instruction",
    "again": "instruction",
    "captured": "captured", "progress": "progress", "complete": "ready",
    "too_short": "problem", "moved": "problem", "not_flat": "problem", "saturated": "problem",
}


def pose_event(kind: str, message: str, time: float, face: str | None = None,
               progress: float | None = None) -> Event:
    """A contract Event for one of the detector's happenings (see EVENT_KIND)."""
    return Event(EVENT_KIND[kind], message, progress, {"kind": kind, "face": face, "time": time})


@dataclass
class Pose:
    """One still pose: its clean samples (raw, m/s^2) and what was found about it."""

    face: str | None
    t: np.ndarray
    samples: np.ndarray
    problem: str | None = None       # None for an accepted pose; else moved / saturated / too_short
    detail: str = ""
    angle_deg: float = float("nan")  # from the nearest face, raw axes (before any calibration)

    @property
    def start(self) -> float:
        return float(self.t[0])

    @property
    def stop(self) -> float:
        return float(self.t[-1])

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if self.t.size > 1 else 0.0

    @property
    def mean(self) -> np.ndarray:
        return self.samples.mean(axis=0)

    @property
    def within_ss(self) -> float:
        return float(np.sum((self.samples - self.mean) ** 2))

    @property
    def noise_sd(self) -> float:
        return float(np.sqrt(self.within_ss / max(3 * (len(self.samples) - 1), 1)))


def classify_face(mean: np.ndarray) -> tuple[str, float]:
    """(nearest face down, angle of the dominant axis from vertical in degrees)."""
    mean = np.asarray(mean, dtype=float)
    k = int(np.argmax(np.abs(mean)))
    norm = float(np.linalg.norm(mean))
    angle = float(np.degrees(np.arccos(min(abs(mean[k]) / norm, 1.0)))) if norm > 0 else 90.0
    face = ("+" if mean[k] < 0 else "-") + AXES[k]
    return face, angle


class PoseDetector:
    """Finds the still poses in a raw stream fed in pieces; says what to tell the operator.

    ``feed(t, raw)`` takes samples (n,) and (n, 3) in m/s^2 and returns the
    events they caused; ``finish()`` closes the pose in progress at the end
    of the data; ``state`` tells a display where the operator stands;
    ``forget(face)`` drops a face; ``accepted()`` are the usable poses.
    """

    def __init__(self, rate: float, g: float = STANDARD_GRAVITY, hold: float = 4.0, min_hold: float = 2.0,
                 window: float = 0.2, still_threshold: float = 0.25, motion_factor: float = 2.0,
                 trim: float = 0.0, lift: float = 0.3, face_tolerance_deg: float = 10.0, drift_block: float = 0.25,
                 drift_tolerance: float = 0.05, settle: float = 1.0, full_scale: float | None = None):
        if not rate or rate <= 0:
            raise DataError("the sample rate must be positive to detect still poses")
        if min_hold > hold:
            raise CalibrationError(f"min_hold {min_hold} s is longer than hold {hold} s")
        self.rate, self.g, self.hold, self.min_hold = float(rate), float(g), float(hold), float(min_hold)
        self.window_n = max(int(round(window * rate)), 5)
        self.trim_n = int(round(trim * rate))
        self.lift_n = int(round(lift * rate))
        self.still_threshold, self.motion_factor = float(still_threshold), float(motion_factor)
        self.face_tolerance_deg = face_tolerance_deg
        self.drift_block_n = max(int(round(drift_block * rate)), 5)
        self.drift_tolerance = drift_tolerance
        self.settle_blocks = int(round(settle / (self.drift_block_n / self.rate)))
        self.full_scale = full_scale
        self.poses: list[Pose] = []          # accepted, in the order captured
        self.rejected: list[Pose] = []       # still stretches that could not be used, with the reason
        self._tail_t = np.empty(0)
        self._tail_x = np.empty((0, 3))
        self._still = False
        self._seg_t: list[np.ndarray] = []
        self._seg_d: list[np.ndarray] = []   # dispersion at each segment sample
        self._seg_x: list[np.ndarray] = []
        self._seg_n = 0
        self._seg_face: str | None = None
        self._seg_flat = False
        self._seg_announced = False
        self._seg_captured = False
        self._seg_problem_reported = False
        self._now = 0.0
        self._drift_checked = 0   # the drift check's holds counted at the last capture (each is said once)

    # ------------------------------------------------------------- progress
    @property
    def _held_captured(self) -> bool:
        """A pose in progress has been captured (held long enough, no problem found): it counts already."""
        return self._still and self._seg_captured and not self._seg_problem_reported

    @property
    def faces_done(self) -> list[str]:
        """Faces with a usable pose: the poses closed, and the one held now once captured."""
        done = ({p.face for p in self.poses if p.angle_deg <= self.face_tolerance_deg}
                | ({self._seg_face} if self._held_captured and self._seg_flat else set()))
        return [f for f in FACES if f in done]

    @property
    def missing_faces(self) -> list[str]:
        done = set(self.faces_done)
        return [f for f in FACES if f not in done]

    def _flat_faces(self) -> list[str]:
        """The faces of the usable flat poses in the order held (the one held now once captured)."""
        faces = [p.face for p in self.poses if p.angle_deg <= self.face_tolerance_deg]
        return faces + ([self._seg_face] if self._held_captured and self._seg_flat else [])

    @property
    def again_rounds(self) -> tuple[dict[str, str], dict[str, str], dict[str, str]]:
        """The drift check's three rounds, each axis -> face.  Round 1: per axis, the first face of that axis
        held after all six faces were done (either face).  Round 2: the opposite face of round 1's, held once
        more after round 1 is through on every axis (each face then held twice, far apart).  Round 3: round
        1's face a third time, after round 2 is through on every axis: at the end of the run, so that its
        three holds span most of it whatever the pace (``noise._shape`` needs half the run)."""
        seen: set[str] = set()
        rounds: tuple[dict[str, str], dict[str, str], dict[str, str]] = ({}, {}, {})
        first, second, third = rounds
        for face in self._flat_faces():
            if len(seen) == len(FACES):
                axis = face[1]
                if axis not in first:
                    first[axis] = face
                elif len(first) == len(AXES) and axis not in second and first[axis] == opposite_face(face):
                    second[axis] = face
                elif len(second) == len(AXES) and axis not in third and first[axis] == face:
                    third[axis] = face
            seen.add(face)
        return rounds

    @property
    def axes_again(self) -> dict[str, str]:
        """The drift check's first round: per axis, the face held again after all six faces were done."""
        return self.again_rounds[0]

    @property
    def again_round(self) -> int | None:
        """The drift check's round under way (1, 2 or 3), None once all three are through."""
        for number, done in enumerate(self.again_rounds, start=1):
            if len(done) < len(AXES):
                return number
        return None

    @property
    def again_missing(self) -> list[str]:
        """The faces to hold again in the round under way: in round 1 per axis not yet checked the face first
        held on it; in round 2 the opposite of the face each axis was held again with in round 1; in round 3
        that round-1 face itself (its third hold)."""
        first_round, second_round, third_round = self.again_rounds
        if len(second_round) == len(AXES):
            return [face for axis, face in first_round.items() if axis not in third_round]
        if len(first_round) == len(AXES):
            return [opposite_face(face) for axis, face in first_round.items() if axis not in second_round]
        first: dict[str, str] = {}
        for face in self._flat_faces():
            first.setdefault(face[1], face)
        # in the order the operator first held them (each face's holds about equally far apart)
        return [face for face in first.values() if face[1] not in first_round] + [
            f"+{axis}" for axis in AXES if axis not in first_round and axis not in first]

    @property
    def complete(self) -> bool:
        """The guided sequence is through: six faces, then one face of each axis again, then its opposite face
        once more, then the first face a third time."""
        return not self.missing_faces and self.again_round is None

    @property
    def state(self) -> dict:
        """Where the operator stands, for a display (the face grid)."""
        held = self._clean_duration() if self._still else 0.0
        return {
            "faces_done": self.faces_done,
            "n_done": len(self.faces_done),
            "n_poses": len(self.poses) + self._held_captured,
            "holds_asked": GUIDED_HOLDS,
            "missing": self.missing_faces,
            "again_done": list(self.axes_again.values()),
            "opposite_done": list(self.again_rounds[1].values()),
            "third_done": list(self.again_rounds[2].values()),
            "again_round": self.again_round,
            "again_missing": self.again_missing,
            "current_face": self._seg_face if self._still and self._seg_flat else None,
            "still": self._still,
            "hold_fraction": min(held / self.hold, 1.0),
            "held_seconds": held,
            # raw mean of the pose held now (the any-orientation flow asks whether it is a new orientation)
            "current_mean": np.concatenate(self._seg_x).mean(axis=0) if self._still and self._seg_n else None,
        }

    def accepted(self) -> list[Pose]:
        """The usable poses: those closed, and the one held now once captured (as it stands, if it
        still passes the checks)."""
        if not self._held_captured:
            return list(self.poses)
        pose, problem = self._settle(self._current_pose(end_clip=0))
        if (problem or self._check(pose)) is not None:
            return list(self.poses)
        return [*self.poses, pose]

    def forget(self, face: str) -> list[Event]:
        """Forget every pose of ``face`` (the operator wants to take it again)."""
        if face not in FACES:
            raise CalibrationError(f"{face!r} is not a face", "faces are +x, -x, +y, -y, +z, -z")
        before = len(self.poses)
        self.poses = [p for p in self.poses if p.face != face]
        n = before - len(self.poses)
        if self._held_captured and self._seg_face == face:
            self._seg_captured = False   # the pose held now is taken again when it qualifies
            n += 1
        self._drift_checked = sum(len(held) for held in self.again_rounds)   # the next hold counts from here
        return [pose_event("redo", f"{face} down forgotten ({n} pose{'s' if n != 1 else ''}): put it down again",
                           self._now, face, len(self.faces_done) / len(FACES))]

    # ----------------------------------------------------------------- feed
    def feed(self, t: np.ndarray, raw: np.ndarray) -> list[Event]:
        t = np.asarray(t, dtype=float).ravel()
        raw = np.asarray(raw, dtype=float).reshape(-1, 3)
        if t.size != raw.shape[0]:
            raise DataError("feed() needs one time per sample")
        if t.size == 0:
            return []
        events: list[Event] = []
        buf_t = np.concatenate([self._tail_t, t])
        buf_x = np.concatenate([self._tail_x, raw])
        offset = self._tail_t.size
        w = self.window_n
        dispersion = np.full(buf_t.size, np.inf)
        if buf_t.size >= w:
            c1 = np.vstack([np.zeros((1, 3)), np.cumsum(buf_x - buf_x[0], axis=0)])
            c2 = np.vstack([np.zeros((1, 3)), np.cumsum((buf_x - buf_x[0]) ** 2, axis=0)])
            s1 = c1[w:] - c1[:-w]
            s2 = c2[w:] - c2[:-w]
            var = np.clip((s2 - s1**2 / w) / (w - 1), 0.0, None)
            dispersion[w - 1:] = np.sqrt(var.sum(axis=1))
        d = dispersion[offset:]
        # Hysteresis, vectorised: the state at each sample is set by whichever came last,
        # a sample below the still threshold or one above the motion threshold.
        idx = np.arange(d.size)
        # The state carried in from the previous block acts as a decisive sample just before this one.
        init_below, init_above = (-1, -2) if self._still else (-2, -1)
        last_below = np.maximum.accumulate(np.where(d < self.still_threshold, idx, init_below))
        last_above = np.maximum.accumulate(np.where(d > self.motion_factor * self.still_threshold, idx, init_above))
        still = last_below > last_above
        # Walk the runs of constant state.
        edges = np.flatnonzero(np.diff(still.astype(np.int8))) + 1
        bounds = np.concatenate([[0], edges, [d.size]])
        for a, b in pairwise(bounds):
            if still[a]:
                if not self._still:
                    # Still since the start of the first quiet window.
                    first = max(offset + a - (w - 1), 0)
                    # The quiet window that opened the pose gets that window's dispersion.
                    self._open_segment(buf_t[first:offset + a], buf_x[first:offset + a],
                                       np.full(offset + a - first, d[a]))
                self._append(buf_t[offset + a:offset + b], buf_x[offset + a:offset + b], d[a:b])
                events += self._segment_events()
            elif self._still:
                events += self._close_segment(motion=True)
        keep = min(w - 1, buf_t.size)
        self._tail_t, self._tail_x = buf_t[buf_t.size - keep:], buf_x[buf_t.size - keep:]
        self._now = float(t[-1])
        return events

    def finish(self) -> list[Event]:
        """End of data: close the pose in progress (a recording may end while still)."""
        return self._close_segment(motion=False) if self._still else []

    # -------------------------------------------------------------- segments
    def _open_segment(self, t: np.ndarray, x: np.ndarray, d: np.ndarray) -> None:
        self._still = True
        self._seg_t, self._seg_x, self._seg_d, self._seg_n = [t], [x], [d], t.size
        self._seg_face, self._seg_flat = None, False
        self._seg_announced = self._seg_captured = self._seg_problem_reported = False

    def _append(self, t: np.ndarray, x: np.ndarray, d: np.ndarray) -> None:
        self._seg_d.append(d)
        self._seg_t.append(t)
        self._seg_x.append(x)
        self._seg_n += t.size

    def _clean_duration(self) -> float:
        return max(self._seg_n - 2 * self.trim_n, 0) / self.rate

    def _segment_events(self) -> list[Event]:
        events = []
        now = float(self._seg_t[-1][-1])
        if not self._seg_announced and self._seg_n >= self.window_n + self.trim_n:
            x = np.concatenate(self._seg_x)
            self._seg_face, angle = classify_face(x.mean(axis=0))
            self._seg_flat = angle <= self.face_tolerance_deg
            self._seg_announced = True
            face = self._seg_face
            if not self._seg_flat:
                events.append(pose_event("not_flat", f"not face down ({angle:.0f} degrees from {face}): kept for the "
                                         "multi-position model; for six faces, put one face flat on the table", now))
            elif not self.missing_faces and face in self.again_missing:
                which = {1: "again (the drift check)", 2: "again (the drift check: the opposite face)",
                         3: "a third time (the drift check's last round)"}[self.again_round]
                events.append(pose_event("hold_still", f"{face} is down {which}: hold still", now,
                                         face))
            elif not self.missing_faces and self.again_round == 1 and face[1] not in self.axes_again:
                events.append(pose_event("hold_still", f"{face} is down again (the drift check): hold still", now, face))
            elif face in self.faces_done:
                events.append(pose_event("already_done", f"{face} already done (holding it adds data)", now, face))
            else:
                events.append(pose_event("hold_still", f"{face} is down: hold still", now, face))
        if (self._seg_announced and not self._seg_captured
                and self._clean_duration() >= self.hold):
            pose, problem = self._settle(self._current_pose(end_clip=0))
            problem = problem or self._check(pose)
            self._seg_captured = True
            if problem is None:
                events.append(pose_event("captured", f"{self._describe(self._seg_face, self._seg_flat)} captured "
                                         f"({self.hold:.1f} s)", now, self._seg_face))
                events += self._count_events(now, self._seg_face)
            else:
                self._seg_problem_reported = True
                events.append(pose_event(problem[0], problem[1], now, self._seg_face))
        return events

    def _current_pose(self, end_clip: int) -> Pose:
        """The segment's clean samples.

        Handling rarely starts or stops abruptly: the dispersion creeps up
        before it crosses the motion threshold and settles after the still
        threshold.  Windows whose dispersion is above 1.5 x the pose's median
        at either end hold some of that motion, so the pose ends before the
        first of them (and starts after the last of them).  One window more
        goes at the start (the pose starts where the first quiet window ends)
        and, when motion ended the pose, ``end_clip`` (a window) and ``lift``
        s at the end: a hand's lift starts as a tilt growing like t^3 that
        reaches a window's sight 0.2-0.7 s later (on imucal's hand-held session
        the last 0.3 s before the dispersion rises already lean by 0.008 m/s^2);
        ``trim`` more at both ends only when asked (default 0: ``_settle``
        finds the rest from the data).
        """
        t = np.concatenate(self._seg_t)
        x = np.concatenate(self._seg_x)
        d = np.concatenate(self._seg_d)
        limit = 1.5 * np.median(d)
        start = 0
        while start < d.size and d[start] > limit:
            start += 1
        # where the first quiet window ends (a segment's first window_n - 1 samples carry its opening window's
        # dispersion): the hand settles below a window's sight
        start = max(start, self.window_n - 1) + self.trim_n
        stop = d.size
        if end_clip:
            while stop > start and d[stop - 1] > limit:
                stop -= 1
            stop -= end_clip + self.lift_n
        stop -= self.trim_n
        t, x = t[start:max(stop, start)], x[start:max(stop, start)]
        face, angle = classify_face(x.mean(axis=0)) if t.size else (None, float("nan"))
        return Pose(face, t, x, angle_deg=angle)

    def _close_segment(self, motion: bool) -> list[Event]:
        """Motion (or the end of data) ends the pose; keep it if it is long, flat, unmoved, unsaturated."""
        self._still = False
        # The window that tripped the motion threshold already holds the motion: drop it.
        pose = self._current_pose(end_clip=self.window_n - 1 if motion else 0)
        now = self._now
        self._seg_t, self._seg_x, self._seg_d, self._seg_n = [], [], [], 0
        pose, problem = self._settle(pose)
        if pose.t.size < 2 or pose.duration < self.min_hold:
            pose.problem, pose.detail = "too_short", f"{pose.duration:.1f} s"
            self.rejected.append(pose)
            if self._seg_announced and motion:
                what = self._describe(pose.face, self._seg_flat)
                return [pose_event("too_short", f"motion detected: {what} held only {pose.duration:.1f} s, "
                                                f"hold it {self.hold:.0f} s", now, pose.face)]
            return []
        problem = problem or self._check(pose)
        if problem is not None:
            pose.problem, pose.detail = problem
            self.rejected.append(pose)
            if self._seg_problem_reported:
                return []
            return [pose_event(problem[0], problem[1], now, pose.face)]
        self.poses.append(pose)
        events = []
        if not self._seg_captured:
            events.append(pose_event("captured", f"{self._describe(pose.face, self._seg_flat)} captured "
                                                 f"({pose.duration:.1f} s)", now, pose.face))
            events += self._count_events(now, pose.face)
        return events

    @staticmethod
    def _describe(face: str | None, flat: bool) -> str:
        if face is None:   # too short to have a face: "still pose (nearest None)" was said
            return "the pose"
        return f"{face} down" if flat else f"still pose (nearest {face})"

    def _count_events(self, now: float, face: str | None) -> list[Event]:
        """What the capture of ``face`` was (a face, a hold of the drift check, or neither), each once; then
        the faces to hold again; 'complete' at the end."""
        n = len(self.faces_done)
        checked = sum(len(held) for held in self.again_rounds)
        if n < len(FACES) or checked == self._drift_checked:
            # after the six, a hold the drift check did not ask for is said as such (not "6 of 6" again)
            text = f"faces {n} of 6" if n < len(FACES) or not self._drift_checked else (
                f"{face or 'a still pose'} held again: not one the drift check asked for")
        else:
            text = f"drift check {checked} of {DRIFT_HOLDS}: {face}"
        self._drift_checked = checked
        events = [pose_event("progress", text, now, progress=n / len(FACES))]
        if n < len(FACES):
            return events
        again, round_ = self.again_missing, self.again_round
        if round_ is None:
            events.append(pose_event("complete", "all six faces captured, and the drift check's three rounds held",
                                     now, progress=1.0))
            return events
        names = ", ".join(again[:-1]) + (" and " if len(again) > 1 else "") + again[-1]
        plural = "s" if len(again) > 1 else ""
        if round_ == 1 and len(again) == 3:
            text = (f"all six faces captured: now put {names} down once more (either face of each axis will "
                    "do), then their opposite faces once more, then the first faces a third time: held far apart, "
                    "the faces show whether the offsets drifted, steadily or in a curve. c computes without it")
        elif round_ == 1:
            text = f"drift check: now put {names} down once more (either face of each axis will do)"
        elif round_ == 2:
            text = (f"drift check, round 2 of 3: now put {names} down once more (the opposite face{plural}), "
                    f"{OPPOSITE_ROUND_WHY}. c computes without it")
        else:
            text = (f"drift check, last round: now put {names} down a third time, {LAST_ROUND_WHY}. "
                    "c computes without it")
        events.append(pose_event("again", text, now))
        return events

    def _check(self, pose: Pose) -> tuple[str, str] | None:
        """The capture checks: (kind, one-line message) of the first problem, or None."""
        x = pose.samples
        if self.full_scale is not None:
            hit = np.any(saturated(x, self.full_scale / COUNT_MAX), axis=1)
            if np.any(hit):
                k = int(np.argmax(hit))
                return ("saturated", f"{pose.face} down at t = {pose.t[k]:.1f} s: {int(hit.sum())} samples at the "
                                     f"sensor's full scale ({self.full_scale:.2f} m/s^2): use a larger range")
        else:
            # Range unknown: a clipped axis sits on one value while the others show noise.
            spread = np.ptp(x, axis=0)
            for k in range(3):
                if spread[k] == 0 and np.any(spread > 0) and abs(x[0, k]) > 0.5 * self.g:
                    return ("saturated", f"{pose.face} down at t = {pose.start:.1f} s: axis {AXES[k]} stuck at "
                                         f"{x[0, k]:.3f} m/s^2 while the others vary (clipped?): use a larger range")
        return None

    def _settle(self, pose: Pose) -> tuple[Pose, tuple[str, str] | None]:
        """Drop settling at the start and the first lift at the end; a shift anywhere else is a move.

        Block means (``drift_block`` s) are compared with their median (the
        pose's plateau).  Up to ``settle`` s of off-plateau blocks at either
        end are normal handling and trimmed away; any other block off the
        plateau by more than the tolerance means the pose moved.
        """
        x, b = pose.samples, self.drift_block_n
        n_blocks = x.shape[0] // b
        if n_blocks < 3:
            return pose, None
        means = x[: n_blocks * b].reshape(n_blocks, b, 3).mean(axis=1)
        deviation = np.linalg.norm(means - np.median(means, axis=0), axis=1)
        # The sd of a block mean: noise_sd / sqrt(b) for white noise; more when the noise is correlated in
        # time (a low-pass filter, 1/f), read from the scatter of successive block means (robustly: the
        # median of their squared differences, so that one step of a move does not raise it).
        block_sd = pose.noise_sd / np.sqrt(b)
        if n_blocks >= 5:
            steps = np.sum(np.diff(means, axis=0) ** 2, axis=1) / 3.0
            block_sd = max(block_sd, float(np.sqrt(np.median(steps) / (2.0 * _CHI2_1_MEDIAN))))
        # Edges: strict, noise-based (4.5 sd of a block mean's offset, beyond the 99.9th percentile of
        # its norm), because a half-settled block left in biases the pose mean at the CRB level.
        edge_off = deviation > 4.5 * block_sd
        # Interior: lenient, so noise never calls a good pose 'moved'.  Successive block means see only the noise
        # faster than a block or two; noise with a memory of seconds wanders the block means over the hold far
        # more than their steps show.  A tip, the way a resting pose moves, turns the vector and leaves |a|
        # unchanged, so the scatter of the blocks' |a| about its median measures the wander the noise alone
        # makes, at every separation the test compares, along one axis of three.  The RMS (not the median):
        # the wander is slow, a pose holds few independent stretches of it.  Only its excess over the fast
        # noise's share (block_sd, already in the tolerance) is the wander, so white noise keeps the old test.
        # MOVED_WANDER_SD such sds make false 'moved' rare (simulated, 2-20 s holds: at most 2 poses in 1000
        # for AR(1) memories up to 2 s, at most 5 in 1000 up to 10 s; with one axis of wander to go on, the
        # estimate's tail, not its median, sets the factor).
        norms = np.linalg.norm(means, axis=1)
        wander_var = max(float(np.mean((norms - np.median(norms)) ** 2)) - block_sd**2, 0.0)
        tolerance = max(self.drift_tolerance, np.hypot(6.0 * block_sd * np.sqrt(2.0),
                                                       MOVED_WANDER_SD * np.sqrt(wander_var)))
        off = deviation > tolerance
        allowance = self.settle_blocks
        lead = 0
        while lead < min(allowance, n_blocks - 1) and edge_off[lead]:
            lead += 1
        tail = 0
        while tail < min(allowance, n_blocks - lead - 1) and edge_off[n_blocks - 1 - tail]:
            tail += 1
        inner = off[lead:n_blocks - tail]
        if np.any(inner):
            k = lead + int(np.argmax(inner))
            size = float(deviation.max())
            deg = np.degrees(np.arcsin(min(size / self.g, 1.0)))
            return pose, ("moved", f"{pose.face} down moved during the pose at t = {pose.t[k * b]:.1f} s "
                                   f"({size:.2f} m/s^2, about {deg:.1f} degrees): hold that face still again")
        stop = x.shape[0] - tail * b if tail else x.shape[0]
        start = lead * b
        # Then sample by sample: the hand's first lift (or last settling) shifts the mean of the last (first)
        # few samples before it raises a whole block; cut where the data show it (_edge_cuts).
        plateau = np.median(means[lead:n_blocks - tail], axis=0)
        sample_var = np.var(x[start:stop], axis=0)
        long_var = sample_var * max(1.0, b * block_sd**2 / max(float(sample_var.mean()), 1e-30))
        cut_start, cut_end = _edge_cuts(x[start:stop] - plateau, long_var, self.settle_blocks * b)
        start, stop = start + cut_start, stop - cut_end
        face, angle = classify_face(x[start:stop].mean(axis=0))
        return Pose(face, pose.t[start:stop], x[start:stop], angle_deg=angle), None


# A stretch of L samples at a pose's end is cut when its summed offset from the plateau S is clear of the
# noise: sum_k S_k^2 / (L var_k) beyond chi^2 with 3 dof at 1e-4 (21.1).  The scan over every length up to
# the settling allowance makes a few hundred correlated looks, and under pure noise its best length can be
# long, so the level is strict: a false cut in about 1 pose of 1000.
EDGE_CHI2 = 21.1


def _edge_cuts(deviation: np.ndarray, long_var: np.ndarray, max_n: int) -> tuple[int, int]:
    """How many samples to cut at the start and at the end of a pose: the length L (<= max_n) whose summed
    deviation from the plateau is the most significant, sum_k S_Lk^2 / (L var_k), when that exceeds
    EDGE_CHI2; else 0.  ``deviation``: (n, 3) samples minus the plateau; ``long_var``: per-axis variance of
    a sample sum's increments (tau x sigma^2 when the noise is correlated)."""
    n = deviation.shape[0]
    max_n = min(int(max_n), n // 4)
    if max_n < 1 or np.any(long_var <= 0):
        return 0, 0
    lengths = np.arange(1, max_n + 1)[:, None]
    cuts = []
    for ordered in (deviation[:max_n], deviation[::-1][:max_n]):
        z = np.sum(np.cumsum(ordered, axis=0) ** 2 / (lengths * long_var), axis=1)
        k = int(np.argmax(z))
        cuts.append(k + 1 if z[k] > EDGE_CHI2 else 0)
    return cuts[0], cuts[1]


def full_scale_of(meta: dict) -> float | None:
    """Sensor full scale in m/s^2 from a recording's metadata or a device's facts, if known."""
    scale = count_scale(meta)
    return None if scale is None else COUNT_MAX * scale
