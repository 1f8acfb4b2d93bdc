"""sim://static: faces down in the operator's order, still poses, handling motion, truth."""

import numpy as np
import pytest

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import DeviceError
from accelrig.procedures.static.fit import face_reference
from accelrig.sim.rigs import RIGS
from accelrig.sim.rigs.static import StaticRig, sensor_with_response
from accelrig.sim.sensor import SensorModel
from accelrig.units import STANDARD_GRAVITY as G


def _rig(url: str, seed: int = 0) -> StaticRig:
    return RIGS["static"].from_url(DeviceURL.parse(url), np.random.default_rng(seed))


def test_face_down_reads_minus_g_on_that_axis_and_poses_are_still():
    rig = _rig("sim://static?order=+z,-z,+x,-x,+y,-y&hold=3")
    truth = rig.truth()
    assert [p["face"] for p in truth["poses"]] == ["+z", "-z", "+x", "-x", "+y", "-y"]
    for pose in truth["poses"]:
        t = np.linspace(pose["start"], pose["stop"] - 1e-6, 50)
        force = rig.specific_force(t)
        assert np.allclose(force, face_reference(pose["face"]), atol=1e-9)
        assert np.allclose(force[0] / G, pose["up_body"])
    assert face_reference("+z")[2] == -G and face_reference("-x")[0] == G


def test_url_plus_signs_arriving_as_spaces_and_repeats_are_accepted():
    rig = _rig("sim://static?order= z, x,-x, x")  # '+' decoded to ' ' by the query parser
    assert rig.order == ("+z", "+x", "-x", "+x")


def test_bad_options_are_refused_with_a_clear_message():
    with pytest.raises(DeviceError, match="not a face"):
        _rig("sim://static?order=+z,+w")
    with pytest.raises(DeviceError, match="pose number"):
        _rig("sim://static?moved=16")


def test_handling_is_realistic_smooth_and_a_few_m_s2():
    rig = _rig("sim://static", seed=3)
    transitions = rig.truth()["transitions"]
    assert len(transitions) == 14   # the default order: six faces, one of each axis again twice, the opposites
    for tr in transitions:
        assert 1.0 <= tr["stop"] - tr["start"] <= 3.0
        t = np.linspace(tr["start"], tr["stop"], 2000)
        force = rig.specific_force(t)
        linear = np.abs(np.linalg.norm(force, axis=1) - G)
        assert 0.3 < linear.max() < 10.0
        # no step at the ends: the force joins the still poses continuously
        assert np.max(np.abs(np.diff(force, axis=0))) < 0.2


def test_same_seed_same_script_and_block_independence():
    a, b = _rig("sim://static?tilt=2", seed=7), _rig("sim://static?tilt=2", seed=7)
    t = np.linspace(0, a.duration, 3001)
    assert np.array_equal(a.specific_force(t), b.specific_force(t))
    assert np.allclose(np.concatenate([a.specific_force(t[:1000]), a.specific_force(t[1000:])]), a.specific_force(t))
    tilts = [p["tilt_deg"] for p in a.truth()["poses"]]
    assert 0 < max(tilts) < 10


def test_moved_pose_tips_in_the_middle_of_its_hold():
    rig = _rig("sim://static?moved=2&moved_deg=3", seed=1)
    pose = rig.truth()["poses"][1]
    assert pose["moved"]["deg"] == pytest.approx(3.0)
    before = rig.specific_force(np.array([pose["start"] + 0.1]))[0]
    after = rig.specific_force(np.array([pose["stop"] - 0.1]))[0]
    angle = np.degrees(np.arccos(before @ after / G**2))
    assert angle == pytest.approx(3.0, abs=1e-6)
    # the handling that follows starts from the tipped pose: no jump where the pose ends
    across = rig.specific_force(pose["stop"] + np.array([-1e-4, 1e-4]))
    assert np.max(np.abs(across[1] - across[0])) < 1e-3


def test_sensor_with_response_reproduces_any_plausible_matrix():
    rng = np.random.default_rng(2)
    for _ in range(5):
        k = SensorModel.random(rng, nonorthogonality=np.deg2rad(rng.uniform(-1, 1, 3))).response_matrix
        sensor = sensor_with_response(k, np.array([0.1, -0.2, 0.3]))
        assert np.allclose(sensor.response_matrix, k, atol=1e-12)
        assert np.allclose(sensor.correction().bias, [0.1, -0.2, 0.3])


def test_tilted_table_tilts_every_pose_by_its_angle_in_a_different_body_direction():
    rig = _rig("sim://static?table=3&order=+z,+z,+z,-x,-x,-x", seed=5)
    truth = rig.truth()
    assert truth["table_deg"] == 3.0
    ups = []
    for pose in truth["poses"]:
        assert pose["kind"] == "face" and pose["tilt_deg"] == pytest.approx(3.0, abs=1e-9)
        force = rig.specific_force(np.array([pose["start"] + 0.5]))[0]
        assert np.allclose(force / G, pose["up_body"])
        ups.append(np.array(pose["up_body"]))
    # the same face down three times: the table's tilt seen in the body frame turns with the random yaw
    across = [u[:2] / np.linalg.norm(u[:2]) for u in ups[:3]]
    assert min(abs(a @ b) for a, b in [(across[0], across[1]), (across[0], across[2]), (across[1], across[2])]) < 0.98


def test_hand_tilt_has_the_stated_sd_per_component():
    components = []
    for seed in range(60):
        for pose in _rig("sim://static?tilt=0.5", seed=seed).truth()["poses"]:
            up = np.array(pose["up_body"])
            k = "xyz".index(pose["face"][1])
            components += [np.degrees(up[j]) for j in range(3) if j != k]
    assert np.std(components) == pytest.approx(0.5, rel=0.1)   # 720 components: sd of the sd 2.6 %
    assert abs(np.mean(components)) < 0.06


def test_arbitrary_orientations_cover_the_sphere_and_say_so_in_the_truth():
    rig = _rig("sim://static?orientations=200&hold=1", seed=2)
    poses = rig.truth()["poses"]
    assert len(poses) == 200 and {p["kind"] for p in poses} == {"arbitrary"} and poses[0]["face"] is None
    ups = np.array([p["up_body"] for p in poses])
    assert np.allclose(np.linalg.norm(ups, axis=1), 1.0)
    assert np.all(np.abs(ups.mean(axis=0)) < 0.15)                       # uniform: mean near 0 ...
    assert np.allclose(ups.T @ ups / len(ups), np.eye(3) / 3, atol=0.07)  # ... second moment I/3
    for pose in poses[:5]:
        t = np.linspace(pose["start"], pose["stop"] - 1e-6, 7)
        assert np.allclose(rig.specific_force(t) / G, pose["up_body"], atol=1e-9)


def test_orientations_refuse_face_options():
    with pytest.raises(DeviceError, match="not both"):
        _rig("sim://static?orientations=10&order=+z,-z")
    with pytest.raises(DeviceError, match="apply to faces"):
        _rig("sim://static?orientations=10&table=2")
