"""Recording a closed-loop walk and exporting it in the formats robot-learning tools read (issue 15).

Each exported file is read back the way its consumer reads it (BeyondMimic's np.load keys, dtypes and
shapes; the Unitree CSV's 36 columns for G1; AMP JSON's keys) and replayed in MuJoCo: body poses within
1 mm / 0.01 rad of the recording. Resampling invariants are hypothesis properties.
"""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.export import export_motion
from engine.export.amp_json import read_amp_json
from engine.export.resample import frame_blend, resample, sample_times, slerp
from engine.export.unitree_csv import UNITREE_G1_29, read_unitree_csv
from engine.gait.command_schedule import parse_command
from engine.gait.style import load_style
from engine.retarget.motion import RobotMotion
from engine.robot.model import load_robot
from engine.walk_recording import load_run_motion, save_run
from engine.walk_runner import run_walk
from studio import cli
from tests.conftest import REPO

WALK_S = 0.6


@pytest.fixture(scope="module")
def g1():
    return load_robot("g1")


@pytest.fixture(scope="module")
def run_file(tmp_path_factory, g1):
    style = load_style(REPO / "styles/g1/neutral.json")
    summary, arrays = run_walk(g1, style, parse_command("0.3,0,0", style.velocities), WALK_S,
                               record_reference=True, command_text="0.3,0,0")
    path = tmp_path_factory.mktemp("run") / "run.npz"
    save_run(path, arrays)
    return path


def _body_poses(robot, motion: RobotMotion) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics of every frame in MuJoCo: (T, B, 3) positions and (T, B, 4) w,x,y,z."""
    model = robot.mj_model
    data = mujoco.MjData(model)
    adr = [int(model.joint(n).qposadr[0]) for n in motion.joint_names]
    pos, quat = [], []
    for row in motion.qpos:
        data.qpos[:7] = row[:7]
        data.qpos[adr] = row[7:]
        mujoco.mj_kinematics(model, data)
        pos.append(data.xpos[1:].copy())
        quat.append(data.xquat[1:].copy())
    return np.array(pos), np.array(quat)


def _angle(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    dot = np.abs(np.sum(q1 * q2, axis=-1))
    return 2 * np.arccos(np.clip(dot, -1.0, 1.0))


def test_the_run_file_is_a_robot_motion_with_its_reference(run_file, g1):
    sim = load_run_motion(run_file)
    ref = load_run_motion(run_file, "reference")
    assert sim.fps == 125.0 and sim.frames == int(WALK_S * 125) and sim.robot == "g1"
    assert sim.joint_names == list(UNITREE_G1_29)  # G1's MuJoCo order is Unitree's
    assert sim.qvel is not None and sim.qvel.shape == (sim.frames, g1.mj_model.nv)
    assert sim.metrics["fell"] is False and sim.source["style"] == "neutral"
    assert ref.qpos.shape == sim.qpos.shape and ref.method == "walk-reference"
    # Standing → walking pose, then tracked: the last frames' joints are within 0.1 rad of the reference.
    assert np.abs(sim.joints[-10:] - ref.joints[-10:]).max() < 0.1
    assert not np.allclose(sim.qpos, ref.qpos)
    with np.load(run_file, allow_pickle=False) as f:  # the analysis arrays of studio walk --out remain
        assert {"t", "com", "kappa", "foot_pos", "reference_qpos"} <= set(f.files)


def test_unitree_csv_has_36_columns_and_replays_the_recording(run_file, g1, tmp_path):
    motion = load_run_motion(run_file)
    export_motion(motion, "unitree-csv", tmp_path / "walk.csv")
    rows = np.loadtxt(tmp_path / "walk.csv", delimiter=",", ndmin=2)  # as csv_to_npz reads it
    assert rows.shape == (motion.frames, 36)
    assert np.allclose(rows[:, 3:7], motion.qpos[:, [4, 5, 6, 3]], atol=1e-8)  # x,y,z,w
    back = RobotMotion(fps=motion.fps, qpos=read_unitree_csv(tmp_path / "walk.csv"), joint_names=list(UNITREE_G1_29),
                       contact=motion.contact, robot="g1", method="csv", foot_names=["left", "right"])
    pos, quat = _body_poses(g1, back)
    pos0, quat0 = _body_poses(g1, motion)
    assert np.abs(pos - pos0).max() < 1e-3 and _angle(quat, quat0).max() < 0.01


def test_unitree_csv_maps_joints_by_name_not_position(tmp_path):
    names = list(reversed(UNITREE_G1_29))[:-1]  # shuffled order, one joint missing
    qpos = np.zeros((3, 7 + len(names)))
    qpos[:, 3] = 1.0
    qpos[:, 7:] = np.arange(len(names)) + 1.0
    motion = RobotMotion(fps=30.0, qpos=qpos, joint_names=names, contact=np.ones((3, 2), bool), robot="g1",
                         method="test", foot_names=["left", "right"])
    export_motion(motion, "unitree-csv", tmp_path / "m.csv")
    rows = np.loadtxt(tmp_path / "m.csv", delimiter=",", ndmin=2)
    for k, name in enumerate(UNITREE_G1_29):
        expected = names.index(name) + 1.0 if name in names else 0.0
        assert rows[0, 7 + k] == expected, name


def test_beyondmimic_npz_is_what_its_loader_reads_and_replays(run_file, g1, tmp_path):
    motion = load_run_motion(run_file)
    export_motion(motion, "beyondmimic-npz", tmp_path / "walk.npz", fps=50)
    data = np.load(tmp_path / "walk.npz")  # whole_body_tracking's MotionLoader: np.load, then these keys
    t_n = len(sample_times(motion.frames, motion.fps, 50.0))
    b_n = g1.mj_model.nbody - 1
    assert data["fps"].dtype == np.int64 and data["fps"].tolist() == [50]
    expect = {"joint_pos": (t_n, 29), "joint_vel": (t_n, 29), "body_pos_w": (t_n, b_n, 3),
              "body_quat_w": (t_n, b_n, 4), "body_lin_vel_w": (t_n, b_n, 3), "body_ang_vel_w": (t_n, b_n, 3)}
    for key, shape in expect.items():
        assert data[key].dtype == np.float32 and data[key].shape == shape, key
    assert data["joint_names"].tolist() == list(UNITREE_G1_29)
    assert data["body_names"][0] == "pelvis"
    # Replay: pelvis pose + joint_pos through MuJoCo give every body pose of the file.
    root = np.concatenate([data["body_pos_w"][:, 0], data["body_quat_w"][:, 0]], axis=1).astype(float)
    replay = RobotMotion(fps=50.0, qpos=np.concatenate([root, data["joint_pos"]], axis=1),
                         joint_names=data["joint_names"].tolist(), contact=np.ones((t_n, 2), bool), robot="g1",
                         method="replay", foot_names=["left", "right"])
    pos, quat = _body_poses(g1, replay)
    assert np.abs(pos - data["body_pos_w"]).max() < 1e-3
    assert _angle(quat, data["body_quat_w"]).max() < 0.01
    # …and they are the recording's poses at the same instants (frames 0, 2.5, 5, … of the 125 Hz run).
    pos0, _ = _body_poses(g1, motion)
    assert np.abs(data["body_pos_w"][::2] - pos0[::5][: len(data["body_pos_w"][::2])]).max() < 1e-3
    # Velocities: the pelvis's linear velocity is the derivative of its position.
    grad = np.gradient(data["body_pos_w"][:, 0].astype(float), 1 / 50.0, axis=0)
    assert np.abs(grad - data["body_lin_vel_w"][:, 0]).max() < 1e-3
    quat_w = data["body_quat_w"]
    assert np.allclose(np.linalg.norm(quat_w, axis=-1), 1.0, atol=1e-5)


def test_amp_json_keys_and_frames(run_file, tmp_path):
    motion = load_run_motion(run_file, "reference")
    written = export_motion(motion, "amp-json", tmp_path / "walk.json", fps=30)
    doc = json.loads((tmp_path / "walk.json").read_text())
    assert {"LoopMode", "FrameDuration", "EnableCycleOffsetPosition", "EnableCycleOffsetRotation", "MotionWeight",
            "Frames"} <= set(doc)
    assert doc["FrameDuration"] == pytest.approx(1 / 30, abs=1e-6)
    assert np.asarray(doc["Frames"]).shape == (written.frames, 7 + 29)
    qpos, names, fps = read_amp_json(tmp_path / "walk.json")
    assert names == motion.joint_names and fps == pytest.approx(30, rel=1e-4)  # FrameDuration has 6 decimals
    assert np.abs(qpos - written.qpos).max() < 2e-6  # 6 decimals


def test_amp_json_replays_the_recording_in_mujoco(run_file, g1, tmp_path):
    """The AMP frames, read back as motion_imitation reads them (root x,y,z, quaternion x,y,z,w, joints),
    replayed through MuJoCo's kinematics: every body within 1 mm / 0.01 rad of the recording at the instants
    both have (30 fps and 125 fps coincide every 0.2 s), and of the resampled recording at every frame."""
    motion = load_run_motion(run_file)
    written = export_motion(motion, "amp-json", tmp_path / "walk.json", fps=30)
    frames = np.asarray(json.loads((tmp_path / "walk.json").read_text())["Frames"], dtype=float)
    root_wxyz = frames[:, [6, 3, 4, 5]]  # motion_imitation stores x,y,z,w
    replay = RobotMotion(fps=30.0, qpos=np.concatenate([frames[:, :3], root_wxyz, frames[:, 7:]], axis=1),
                         joint_names=list(motion.joint_names), contact=np.ones((len(frames), 2), bool), robot="g1",
                         method="replay", foot_names=["left", "right"])
    pos, quat = _body_poses(g1, replay)
    pos_w, quat_w = _body_poses(g1, written)
    assert np.abs(pos - pos_w).max() < 1e-3 and _angle(quat, quat_w).max() < 0.01
    pos0, quat0 = _body_poses(g1, motion)
    k = np.arange(0, len(frames), 6)  # 0, 0.2, 0.4 s
    k = k[25 * (k // 6) < motion.frames]
    assert len(k) >= 3
    assert np.abs(pos[k] - pos0[25 * (k // 6)]).max() < 1e-3
    assert _angle(quat[k], quat0[25 * (k // 6)]).max() < 0.01


# ----------------------------------------------------------------------------- resampling invariants


def _random_motion(seed: int, frames: int, fps: float) -> RobotMotion:
    rng = np.random.default_rng(seed)
    qpos = np.cumsum(rng.normal(0, 0.05, (frames, 7 + 3)), axis=0)
    quat = rng.normal(size=(frames, 4))
    quat[1:] = quat[0] + np.cumsum(rng.normal(0, 0.2, (frames - 1, 4)), axis=0)
    quat *= np.where(rng.random(frames) < 0.3, -1.0, 1.0)[:, None]  # sign flips: the same rotations
    qpos[:, 3:7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    return RobotMotion(fps=fps, qpos=qpos, joint_names=["a", "b", "c"], contact=rng.random((frames, 2)) < 0.5,
                       robot="g1", method="test", foot_names=["left", "right"], qvel=rng.normal(size=(frames, 9)))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), frames=st.integers(2, 60), fps_in=st.sampled_from([25.0, 30.0, 50.0, 60.0, 125.0]),
       fps_out=st.floats(5.0, 300.0))
def test_resampling_invariants(seed, frames, fps_in, fps_out):
    motion = _random_motion(seed, frames, fps_in)
    out = resample(motion, fps_out)
    span = (frames - 1) / fps_in
    # frame count: every output instant k / fps inside the recording's span, the first at 0
    assert out.frames == int(np.floor(span * fps_out + 1e-9)) + 1 and (out.frames - 1) / fps_out <= span + 1e-9
    assert np.allclose(out.qpos[0], motion.qpos[0])
    assert np.allclose(np.linalg.norm(out.base_quat, axis=1), 1.0)
    # positions and joints stay between the two input frames they blend (lerp is convex)
    i0, i1, _ = frame_blend(np.arange(out.frames) / fps_out, frames, fps_in)
    cols = [0, 1, 2, 7, 8, 9]
    lo = np.minimum(motion.qpos[i0][:, cols], motion.qpos[i1][:, cols]) - 1e-9
    hi = np.maximum(motion.qpos[i0][:, cols], motion.qpos[i1][:, cols]) + 1e-9
    assert np.all((out.qpos[:, cols] >= lo) & (out.qpos[:, cols] <= hi))
    # the root rotation lies on the shortest arc: never further from either end than they are apart
    gap = _angle(motion.base_quat[i0], motion.base_quat[i1])
    assert np.all(_angle(out.base_quat, motion.base_quat[i0]) <= gap + 1e-6)
    assert np.all(_angle(out.base_quat, motion.base_quat[i1]) <= gap + 1e-6)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), frames=st.integers(2, 40), k=st.integers(2, 5))
def test_resampling_keeps_coincident_frames_and_same_rate_is_identity(seed, frames, k):
    motion = _random_motion(seed, frames, 120.0)
    assert resample(motion, 120.0) is motion
    down = resample(motion, 120.0 / k)  # every k-th input frame exactly
    assert np.allclose(down.qpos, motion.qpos[::k][: down.frames]) or np.allclose(
        down.qpos[:, 7:], motion.qpos[::k, 7:][: down.frames])
    same_rot = _angle(down.base_quat, motion.base_quat[::k][: down.frames])
    assert same_rot.max() < 1e-6
    up = resample(motion, 120.0 * k)  # upsampled then back: the original frames
    back = resample(up, 120.0)
    assert back.frames == motion.frames
    assert np.allclose(back.qpos[:, 7:], motion.qpos[:, 7:]) and _angle(back.base_quat, motion.base_quat).max() < 1e-6


@given(blend=st.floats(0.0, 1.0), seed=st.integers(0, 1000))
def test_slerp_does_not_depend_on_the_quaternion_sign(blend, seed):
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=(2, 1, 4))
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    assert _angle(slerp(a, b, np.array([blend])), slerp(a, -b, np.array([blend])))[0] < 1e-6


# ----------------------------------------------------------------------------- bad input: one line, exit 2


@pytest.mark.parametrize("extra, expected", [
    (["--format", "amp-json", "--fps", "0"], "--fps: expected 0 < fps ≤ 1000, got 0.0"),
    (["--format", "amp-json", "--fps", "-30"], "--fps: expected 0 < fps ≤ 1000, got -30.0"),
    (["--format", "amp-json", "--fps", "nan"], "--fps: expected 0 < fps ≤ 1000, got nan"),
    (["--format", "unitree-csv", "--take", "reference"], "plain.npz: reference_qpos: missing"),
])
def test_export_bad_input_is_one_line(tmp_path, capsys, extra, expected):
    motion = _random_motion(0, 5, 30.0)
    motion.save(tmp_path / "plain.npz")
    out = tmp_path / ("out.json" if "amp-json" in extra else "out.csv")
    rc = cli.main(["export", str(tmp_path / "plain.npz"), "--out", str(out), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and expected in err[0], err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["plain.npz"]


def test_export_unknown_format_and_unreadable_file(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(["export", "x.npz", "--format", "bvh", "--out", str(tmp_path / "x.bvh")])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "invalid choice: 'bvh'" in err[0]
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    rc = cli.main(["export", str(tmp_path / "bad.npz"), "--format", "beyondmimic-npz", "--out", str(tmp_path / "o.npz")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("studio: error: bad.npz: expected an npz archive"), err
    assert not (tmp_path / "o.npz").exists()
