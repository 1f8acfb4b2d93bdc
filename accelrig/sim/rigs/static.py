"""Static calibration: still poses (faces down, or any orientation) with handling between them.

Convention ("face X down"): the cube rests on its X face, so the sensor's X
axis points DOWN and, at rest, reads -g (specific force: the axis pointing
up reads +g).  "+z down" reads az = -g, "-z down" reads az = +g.

The script, drawn once from the seeded generator: pose k is held still for
``hold`` s; between poses the operator lifts the cube, turns it smoothly
(minimum-jerk rotation) onto the next face, shakes it a little (a few
m/s^2 at 2-6 Hz) and puts it down, in 1-3 s.  The sensor sits at the centre
the cube turns about; its trajectory (lift and shake as displacements, the
orientation) goes through accelrig.sim.kinematics.  Each pose has a random yaw on
the table (invisible to gravity) and two kinds of tilt a calibration that
takes the faces as exact references cannot tell from a sensor error:

  tilt=S    the hand: each pose tilted at random, each of the two horizontal
            components N(0, S^2) degrees (the same definition as the six-face
            fit's pose flatness);
  table=D   the table: its top tilted by D degrees in a random direction,
            drawn once; with the random yaw of each pose the same table tilt
            appears in a different direction in each pose's body frame.

``orientations=N`` replaces the faces by N orientations drawn uniformly over
all rotations (the multi-position calibration: the sensor held still against
a fixture in any orientation), with the same handling between them.
``moved=K`` makes pose K (1-based) slowly tip by ``moved_deg`` in the middle
of its hold, for the 'moved during pose' check.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.special import ndtr

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError
from accelrig.geometry import FACES
from accelrig.sim import kinematics
from accelrig.sim.rigs.base import Rig
from accelrig.sim.sensor import SensorModel
from accelrig.units import STANDARD_GRAVITY

# The wizard's sequence: the six faces, then one face of each axis again, then the opposite faces once more,
# then the first faces a third time (the drift check's three rounds; poses.PoseDetector.again_rounds)
DEFAULT_ORDER = ("+z", "-z", "+x", "-x", "+y", "-y", "+z", "+x", "+y", "-z", "-x", "-y", "+z", "+x", "+y")

# Rotation (body -> world) that puts the named body axis pointing down (-z world).
_FACE_DOWN = {
    "+z": Rotation.from_euler("x", np.pi),
    "-z": Rotation.identity(),
    "+x": Rotation.from_euler("y", np.pi / 2),
    "-x": Rotation.from_euler("y", -np.pi / 2),
    "+y": Rotation.from_euler("x", -np.pi / 2),
    "-y": Rotation.from_euler("x", np.pi / 2),
}


def parse_faces(text: str) -> tuple[str, ...]:
    """'+z,-z,+x' -> ('+z', '-z', '+x'); a '+' arriving as a space from a URL query is restored."""
    faces = []
    for item in text.split(","):
        face = item.strip().replace(" ", "+")
        if len(face) == 1 and face in "xyz":
            face = "+" + face
        if face not in FACES:
            raise DeviceError(f"{item.strip()!r} is not a face", "faces are +x, -x, +y, -y, +z, -z, comma separated")
        faces.append(face)
    if not faces:
        raise DeviceError("order= names no face", "e.g. order=+z,-z,+x,-x,+y,-y")
    return tuple(faces)


def _down(face: str) -> np.ndarray:
    """Unit vector of the body axis that points down with ``face`` down (the rig's own, from _FACE_DOWN)."""
    return _FACE_DOWN[face].inv().apply([0.0, 0.0, -1.0])


def _min_jerk(s: np.ndarray) -> np.ndarray:
    return s**3 * (10 - 15 * s + 6 * s**2)


class StaticRig(Rig):
    name = "static"
    description = ("static calibration: still poses (faces down, or any orientation with orientations=N) "
                   "with handling motion between them")
    options = {
        "order": "faces down in the operator's order, comma separated (default +z,-z,+x,-x,+y,-y,+z,+x,+y,-z,-x,-y,+z,+x,+y: the six faces, then one of each axis again, then the opposite faces once more, then the first faces a third time); repeats allowed",
        "hold": "seconds each pose is held still (default 4)",
        "tilt": "hand placement: sd of each of the two components of a pose's random tilt from face-down, "
                "degrees (default 0)",
        "table": "table tilt, degrees, in a random direction drawn once; each pose's random yaw shows it in a "
                 "different direction in the body frame (default 0: levelled)",
        "orientations": "N still poses in orientations uniform over all rotations instead of the faces "
                        "(multi-position calibration; not with order, tilt or table)",
        "shake": "peak handling acceleration between poses, m/s^2 (default 3)",
        "moved": "1-based pose that tips slowly in the middle of its hold (default: none)",
        "moved_deg": "how far that pose tips, degrees (default 3)",
    }

    def __init__(self, rng: np.random.Generator, order=DEFAULT_ORDER, hold: float = 4.0, tilt_deg: float = 0.0,
                 shake: float = 3.0, moved: int | None = None, moved_deg: float = 3.0, g: float = STANDARD_GRAVITY,
                 table_deg: float = 0.0, orientations: int | None = None):
        if hold <= 0:
            raise DeviceError(f"hold={hold} must be positive")
        if tilt_deg < 0 or shake < 0 or table_deg < 0:
            raise DeviceError("tilt, table and shake must not be negative")
        if orientations is not None:
            if orientations < 1:
                raise DeviceError(f"orientations={orientations} must be at least 1")
            if tilt_deg or table_deg:
                raise DeviceError("tilt and table apply to faces, not to orientations=N (already any orientation)")
            order = (None,) * orientations
        order = tuple(order)
        if moved is not None and not 1 <= moved <= len(order):
            raise DeviceError(f"moved={moved} is not a pose number (1..{len(order)})")
        self.order, self.hold, self.tilt_deg, self.shake, self.g = order, float(hold), float(tilt_deg), float(shake), g
        self.moved, self.moved_deg = moved, float(moved_deg)
        self.table_deg, self.orientations = float(table_deg), orientations
        # The table's tilt (world frame), drawn only when asked so a seed's script without it is unchanged.
        table_heading = rng.uniform(0, 2 * np.pi) if table_deg > 0 else 0.0
        self._table = Rotation.from_rotvec(np.deg2rad(table_deg) * np.array([np.cos(table_heading),
                                                                            np.sin(table_heading), 0.0]))

        # Still orientations: face down, random yaw, small random hand tilt about a horizontal axis, the table.
        self._poses: list[dict] = []
        self._transitions: list[dict] = []
        t = 0.0
        previous = None
        for k, face in enumerate(order):
            yaw = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi))
            heading = rng.uniform(0, 2 * np.pi)
            # Hand tilt: isotropic 2-D Gaussian of sd tilt_deg per component = a uniform heading and a Rayleigh
            # radius, the radius from the normal draw through its CDF (the same three draws per pose as
            # always, so a seed's script does not depend on the tilt asked for).
            radius = tilt_deg * np.sqrt(-2.0 * np.log(max(float(ndtr(rng.normal())), 1e-300)))
            tilt = Rotation.from_rotvec(np.deg2rad(radius) * np.array([np.cos(heading), np.sin(heading), 0.0]))
            if face is None:
                orientation = Rotation.random(random_state=rng)
            else:
                orientation = self._table * tilt * yaw * _FACE_DOWN[face]
            if previous is not None:
                duration = rng.uniform(1.0, 3.0)
                freqs = rng.uniform(2.0, 6.0, (3, 3))
                phases = rng.uniform(0, 2 * np.pi, (3, 3))
                amps = rng.uniform(0.3, 1.0, (3, 3))
                amps *= shake / max(amps.sum(axis=1).max(), 1e-12)  # peak about shake on every world axis
                self._transitions.append(dict(start=t, stop=t + duration, a=previous, b=orientation,
                                              lift=rng.uniform(0.03, 0.08), freqs=freqs, phases=phases, amps=amps))
                t += duration
            up_body = orientation.inv().apply([0.0, 0.0, 1.0])
            pose = dict(face=face, start=t, stop=t + self.hold, rotation=orientation,
                        tilt_deg=float(np.degrees(np.arccos(np.clip(-up_body @ _down(face), -1, 1))))
                        if face else None)
            if moved == k + 1:
                axis = np.array([np.cos(heading + 1.0), np.sin(heading + 1.0), 0.0])
                pose["tip"] = dict(start=t + 0.4 * self.hold, stop=t + 0.6 * self.hold,
                                   rotvec=np.deg2rad(moved_deg) * axis)
            self._poses.append(pose)
            # the next handling starts where this pose ended: tipped, if it tipped
            previous = self._pose_rotation(pose, np.array([pose["stop"]]))[0] if "tip" in pose else orientation
            t += self.hold
        self.duration = t

    @classmethod
    def from_url(cls, url: DeviceURL, rng: np.random.Generator) -> StaticRig:
        order = parse_faces(url.get_str("order")) if url.get_str("order") else DEFAULT_ORDER
        orientations = url.get_int("orientations", low=1, high=1000)
        if orientations is not None and url.get_str("order"):
            raise DeviceError("give either order= (faces) or orientations=N (any orientation), not both")
        return cls(rng, order=order, hold=url.get_float("hold", 4.0, low=0.0, low_open=True, high=3600.0, unit="s"),
                   tilt_deg=url.get_float("tilt", 0.0, low=0.0, high=90.0, unit="deg"),
                   shake=url.get_float("shake", 3.0, low=0.0, high=100.0, unit="m/s^2"),
                   moved=url.get_int("moved"),   # the rig says which pose numbers exist
                   moved_deg=url.get_float("moved_deg", 3.0, low=0.0, high=180.0, unit="deg"),
                   table_deg=url.get_float("table", 0.0, low=-90.0, high=90.0, unit="deg"),
                   orientations=orientations)

    def _pose_rotation(self, pose: dict, t: np.ndarray) -> Rotation:
        tip = pose.get("tip")
        if tip is None:
            return Rotation.concatenate([pose["rotation"]] * t.size) if t.size else pose["rotation"]
        s = _min_jerk(np.clip((t - tip["start"]) / (tip["stop"] - tip["start"]), 0.0, 1.0))
        return Rotation.from_rotvec(s[:, None] * tip["rotvec"]) * pose["rotation"]

    def orientation(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float).ravel()
        rotation = np.empty((t.size, 3, 3))
        # Before the first pose or after the last one the cube rests in that pose.
        for k, pose in enumerate(self._poses):
            lo = -np.inf if k == 0 else pose["start"]
            hi = np.inf if k == len(self._poses) - 1 else pose["stop"]
            mask = (t >= lo) & (t < hi)
            if np.any(mask):
                rotation[mask] = self._pose_rotation(pose, t[mask]).as_matrix()
        for tr in self._transitions:
            mask = (t >= tr["start"]) & (t < tr["stop"])
            if np.any(mask):
                s = (t[mask] - tr["start"]) / (tr["stop"] - tr["start"])
                relative = (tr["a"].inv() * tr["b"]).as_rotvec()
                rotation[mask] = (tr["a"] * Rotation.from_rotvec(_min_jerk(s)[:, None] * relative)).as_matrix()
        return rotation

    def position(self, t: np.ndarray) -> np.ndarray:
        """Still on the table but for the handling: a lift and a shake, both fading in and out."""
        t = np.asarray(t, dtype=float).ravel()
        position = np.zeros((t.size, 3))
        for tr in self._transitions:
            mask = (t >= tr["start"]) & (t < tr["stop"])
            if not np.any(mask):
                continue
            tt = t[mask]
            # sin^4 starts and ends with zero displacement, speed, acceleration and jerk:
            # the hand joins the still poses smoothly
            envelope = np.sin(np.pi * (tt - tr["start"]) / (tr["stop"] - tr["start"])) ** 4
            angular = 2 * np.pi * tr["freqs"][None]
            # each shake term has acceleration amplitude amps (displacement amps / angular^2)
            shake = (tr["amps"][None] / angular**2 * np.sin(angular * tt[:, None, None] + tr["phases"][None])).sum(axis=2)
            position[mask] = envelope[:, None] * shake
            position[mask, 2] += tr["lift"] * envelope
        return position

    def specific_force(self, t: np.ndarray) -> np.ndarray:
        return kinematics.specific_force(self.position, self.orientation, t, self.g)

    def truth(self) -> dict:
        poses = []
        up = np.array([0.0, 0.0, 1.0])
        for pose in self._poses:
            entry = {
                "kind": "face" if pose["face"] else "arbitrary",
                "face": pose["face"],
                "start": pose["start"],
                "stop": pose["stop"],
                # angle of the true down direction from the face's (hand and table together); None if arbitrary
                "tilt_deg": pose["tilt_deg"],
                "rotation": pose["rotation"].as_matrix().tolist(),
                # unit 'up' direction in the body frame: the still specific force is g times this
                "up_body": pose["rotation"].inv().apply(up).tolist(),
            }
            if "tip" in pose:
                entry["moved"] = {"start": pose["tip"]["start"], "stop": pose["tip"]["stop"],
                                  "deg": float(np.rad2deg(np.linalg.norm(pose["tip"]["rotvec"])))}
            poses.append(entry)
        return {
            "rig": self.name,
            "g": self.g,
            "order": list(self.order),
            "hold": self.hold,
            "tilt_deg": self.tilt_deg,
            "table_deg": self.table_deg,
            "table_rotation": self._table.as_matrix().tolist(),
            "orientations": self.orientations,
            "poses": poses,
            "transitions": [{"start": tr["start"], "stop": tr["stop"]} for tr in self._transitions],
        }


def sensor_with_response(response: np.ndarray, offset: np.ndarray, **kwargs) -> SensorModel:
    """A SensorModel whose raw = K f + o has exactly the given K.

    K = L Q (LQ decomposition): L lower triangular = diag(gain) T(nonorthogonality),
    Q = R(misalignment).  Lets tests and benchmarks draw the truth inside a
    chosen model family (e.g. the paper's C = G R) and still simulate through
    the ordinary sensor model.
    """
    k = np.asarray(response, dtype=float)
    q, r = np.linalg.qr(k.T)
    lower, rot = r.T, q.T
    signs = np.sign(np.diag(lower))
    lower, rot = lower * signs, signs[:, None] * rot
    if np.linalg.det(rot) < 0:
        raise ValueError("response matrix must have a positive determinant")
    gain = np.linalg.norm(lower, axis=1)
    nonorth = np.arcsin([lower[1, 0] / lower[1, 1], lower[2, 0] / lower[2, 2], lower[2, 1] / lower[2, 2]])
    c, b, a = Rotation.from_matrix(rot).as_euler("ZYX")
    sensor = SensorModel(offset=offset, gain=gain, misalignment=np.array([a, b, c]), nonorthogonality=nonorth, **kwargs)
    if not np.allclose(sensor.response_matrix, k, atol=1e-12):
        raise ValueError("response matrix outside the sensor model's range (non-orthogonality too large)")
    return sensor
