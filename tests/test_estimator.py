"""State estimator (paper Sec. 7.2): IMU EKF on synthetic data, G1/Go1 in MuJoCo with sensor noise,
contact-flag switches, truth pass-through, garbage rejection."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.control.controller import RobotState
from engine.control.estimation import (
    EstimatorParams,
    ImuEkf,
    ImuEkfParams,
    ImuNoise,
    ImuSample,
    LegKinematics,
    MujocoImu,
    StateEstimator,
)
from engine.control.estimation.ekf import _inv_sym
from engine.control.estimation.quaternion import _quat_step
from engine.bench.estimator import benchmark_estimator
from engine.robot.model import load_robot
from engine.sim import Simulation

DT_S = 0.002
GRAVITY_MPS2 = 9.81
# A MEMS IMU with uncalibrated turn-on biases (≈0.3 °/s, ≈3–5 mg) and noisy encoders.
REALISTIC_IMU = ImuNoise(gyro_noise_density_radps_rthz=3e-4, gyro_bias_radps=(0.004, -0.003, 0.005),
                         accel_noise_density_mps2_rthz=2e-3, accel_bias_mps2=(0.03, -0.02, 0.05))
ENCODER_STD_RAD = 1e-4
ENCODER_RATE_STD_RADPS = 0.02


# ----------------------------------------------------------------------------- helpers


@dataclass
class Tick:
    t_s: float
    imu: ImuSample
    joint_q: np.ndarray
    joint_qd: np.ndarray
    truth: RobotState


@dataclass
class Recording:
    robot_name: str
    init: RobotState
    ticks: list[Tick]


def record(robot_name: str, duration_s: float, pushes: list[tuple[float, tuple[float, float, float]]], seed: int = 1,
           push_duration_s: float = 0.3) -> Recording:
    """Stand the robot under the default standing controller, push it, record noisy sensors and truth."""
    robot = load_robot(robot_name)
    sim = Simulation(robot)
    imu = MujocoImu(robot.mj_model, REALISTIC_IMU, seed=seed)
    rng = np.random.default_rng(seed + 100)
    init = sim.state()
    ticks = []
    pending = sorted(pushes)
    for _ in range(int(round(duration_s / DT_S))):
        while pending and sim.time_s >= pending[0][0] - 1e-9:
            sim.push(np.array(pending.pop(0)[1]), push_duration_s)
        sim.step()
        assert not sim.fallen
        ticks.append(Tick(sim.time_s, imu.read(sim.data),
                          sim.joint_positions() + rng.normal(0.0, ENCODER_STD_RAD, robot.n_joints),
                          sim.joint_velocities() + rng.normal(0.0, ENCODER_RATE_STD_RADPS, robot.n_joints),
                          sim.state()))
    return Recording(robot_name, init, ticks)


def rpy(q: np.ndarray) -> np.ndarray:
    return pin.rpy.matrixToRpy(pin.Quaternion(q[3:7]).toRotationMatrix())


def errors(est: RobotState, truth: RobotState) -> dict[str, np.ndarray]:
    """Roll/pitch/yaw error (rad), position error (m), world-frame base velocity error (m/s)."""
    r_est = pin.Quaternion(est.q[3:7]).toRotationMatrix()
    r_true = pin.Quaternion(truth.q[3:7]).toRotationMatrix()
    d = rpy(est.q) - rpy(truth.q)
    d = (d + np.pi) % (2 * np.pi) - np.pi
    return {"rpy": d, "pos": est.q[:3] - truth.q[:3], "vel": r_est @ est.v[:3] - r_true @ truth.v[:3]}


def replay(rec: Recording, estimator: StateEstimator, contact_fn=None) -> tuple[list[RobotState], dict[str, np.ndarray]]:
    estimator.reset(rec.init)
    n_feet = len(estimator.foot_names)
    states, errs = [], {"rpy": [], "pos": [], "vel": []}
    for tick in rec.ticks:
        contact = np.ones(n_feet, dtype=bool) if contact_fn is None else contact_fn(tick.t_s)
        s = estimator.update(tick.t_s, tick.imu, tick.joint_q, tick.joint_qd, contact)
        states.append(s)
        for k, v in errors(s, tick.truth).items():
            errs[k].append(v)
    return states, {k: np.array(v) for k, v in errs.items()}


@pytest.fixture(scope="module")
def g1_pushed() -> Recording:
    # 40 N sideways and 25 N forward, 0.3 s each (40 N forward topples G1 under the standing PD).
    return record("g1", 5.0, [(0.5, (0.0, 40.0, 0.0)), (2.5, (25.0, 0.0, 0.0))])


@pytest.fixture(scope="module")
def g1_quiet() -> Recording:
    return record("g1", 3.0, [], seed=7)


# ----------------------------------------------------------------------------- (1) EKF, synthetic


def _static_imu(rng, rot, bias, n):
    for _ in range(n):
        gyro = bias + rng.normal(0.0, 3e-4 / math.sqrt(DT_S), 3)
        accel = rot.T @ np.array([0.0, 0.0, GRAVITY_MPS2]) + rng.normal(0.0, 2e-3 / math.sqrt(DT_S), 3)
        yield gyro, accel


def test_ekf_static_imu_converges_to_roll_pitch_and_learns_the_gyro_bias():
    rng = np.random.default_rng(0)
    roll, pitch, yaw = math.radians(3.0), math.radians(-2.0), math.radians(30.0)
    rot = pin.rpy.rpyToMatrix(roll, pitch, yaw)
    bias = np.array([0.006, -0.004, 0.003])
    ekf = ImuEkf(ImuEkfParams(), GRAVITY_MPS2)
    samples = _static_imu(rng, rot, bias, 5000)
    gyro, accel = next(samples)
    assert ekf.initialize(accel, yaw)
    assert np.degrees(np.abs(pin.rpy.matrixToRpy(rot.T @ ekf.rotation)[:2])).max() < 1.0  # one noisy sample
    for gyro, accel in samples:
        ekf.propagate(gyro, DT_S)
        assert ekf.update_gravity(accel, dt_s=DT_S)
    err = pin.rpy.matrixToRpy(rot.T @ ekf.rotation)
    assert np.degrees(np.abs(err[:2])).max() < 0.5
    bias_err = ekf.gyro_bias_radps - bias
    assert np.abs(bias_err[:2]).max() < 1e-3  # from 6e-3 / 4e-3
    # Yaw is unobservable from gravity: it drifts with the (nearly) unobserved vertical bias.
    t_s = 4999 * DT_S
    assert abs(abs(err[2]) - abs(bias[2]) * t_s) < 0.3 * abs(bias[2]) * t_s


def test_ekf_stance_yaw_rate_observes_the_vertical_bias():
    rng = np.random.default_rng(1)
    rot = pin.rpy.rpyToMatrix(0.01, -0.02, 1.0)
    bias = np.array([0.003, -0.002, 0.006])
    ekf = ImuEkf(ImuEkfParams(), GRAVITY_MPS2)
    samples = _static_imu(rng, rot, bias, 5000)
    ekf.initialize(next(samples)[1], 1.0)
    for gyro, accel in samples:
        ekf.propagate(gyro, DT_S)
        ekf.update_gravity(accel, dt_s=DT_S)
        # A flat foot in stance, still relative to the base, with noisy joint rates.
        ekf.update_stance_yaw_rate(gyro, rng.normal(0.0, 0.02, 3), n_feet=2)
    err = pin.rpy.matrixToRpy(rot.T @ ekf.rotation)
    assert abs(ekf.gyro_bias_radps[2] - bias[2]) < 5e-4
    assert abs(math.degrees(err[2])) < 0.3  # 6e-3 rad/s unobserved would be 1.7° after 10 s
    assert np.degrees(np.abs(err[:2])).max() < 0.5


def test_ekf_rejects_a_garbage_accelerometer_sample():
    ekf = ImuEkf(ImuEkfParams(), GRAVITY_MPS2)
    assert not ekf.initialize(np.array([np.nan, 0.0, 9.81]), 0.0)
    assert ekf.initialize(np.array([0.0, 0.0, 9.81]), 0.0)
    before = (ekf.quat_wxyz, ekf.cov.copy())
    assert not ekf.update_gravity(np.array([np.nan, 0.0, 9.81]))
    assert not ekf.update_gravity(np.array([0.0, 0.0, 40.0]))  # an impact beyond the gate
    assert ekf.quat_wxyz == before[0] and np.array_equal(ekf.cov, before[1])


# ----------------------------------------------------------------------------- (2) G1 with pushes


def test_g1_standing_with_pushes_tracks_orientation_height_and_velocity(g1_pushed):
    robot = load_robot("g1")
    est = StateEstimator(robot)
    _, e = replay(g1_pushed, est)
    rp_deg = np.degrees(np.abs(e["rpy"][:, :2]))
    height_mm = 1e3 * np.abs(e["pos"][:, 2])
    vel_rms = np.sqrt(np.mean(e["vel"] ** 2, axis=0))
    print(f"\nG1 pushes: max roll/pitch error {rp_deg.max():.2f}° (rms {np.sqrt(np.mean(rp_deg ** 2)):.2f}°), "
          f"yaw drift {np.degrees(np.abs(e['rpy'][:, 2])).max():.2f}°, max height error {height_mm.max():.1f} mm, "
          f"max xy error {1e3 * np.abs(e['pos'][:, :2]).max():.1f} mm, velocity rms {np.round(vel_rms, 4)} m/s")
    assert rp_deg.max() < 1.0
    assert height_mm.max() < 10.0
    assert vel_rms.max() < 0.02
    assert np.abs(e["vel"]).max() < 0.1
    assert np.abs(e["pos"][:, :2]).max() < 0.03
    assert est.ekf.gravity_updates > 0.9 * len(g1_pushed.ticks) / est.params.correction_divider
    # The estimate is not just the prior: the base really moved during the pushes.
    truth_speed = np.array([np.linalg.norm(t.truth.v[:3]) for t in g1_pushed.ticks])
    assert truth_speed.max() > 0.05
    assert np.abs(e["vel"]).max() < 0.5 * truth_speed.max()


def test_linear_acceleration_compensation_beats_the_raw_gravity_direction(g1_pushed):
    robot = load_robot("g1")
    _, comp = replay(g1_pushed, StateEstimator(robot))
    _, raw = replay(g1_pushed, StateEstimator(robot, params=EstimatorParams(linear_accel_compensation=False)))
    comp_rp = np.abs(comp["rpy"][:, :2]).max()
    raw_rp = np.abs(raw["rpy"][:, :2]).max()
    print(f"\nmax roll/pitch error: compensated {math.degrees(comp_rp):.2f}°, raw gravity direction {math.degrees(raw_rp):.2f}°")
    assert comp_rp < raw_rp


def test_go1_point_feet_standing():
    rec = record("go1", 2.0, [(0.5, (0.0, 15.0, 0.0))], push_duration_s=0.2)
    _, e = replay(rec, StateEstimator(load_robot("go1")))
    assert np.degrees(np.abs(e["rpy"][:, :2])).max() < 1.0
    assert np.degrees(np.abs(e["rpy"][:, 2])).max() < 0.5  # the contact polygon's spin observes the yaw bias
    assert 1e3 * np.abs(e["pos"][:, 2]).max() < 10.0
    assert np.sqrt(np.mean(e["vel"] ** 2, axis=0)).max() < 0.02


# ----------------------------------------------------------------------------- (3) contact switches


def test_dropping_and_restoring_contact_flags_causes_no_jumps(g1_quiet):
    robot = load_robot("g1")

    def swings(t_s: float) -> np.ndarray:
        c = np.ones(2, dtype=bool)
        c[0] = not (0.8 <= t_s < 1.2)  # left "swing"
        c[1] = not (1.8 <= t_s < 2.2)  # right "swing"
        return c

    ref, e_ref = replay(g1_quiet, StateEstimator(robot))
    est = StateEstimator(robot)
    out, e = replay(g1_quiet, est, swings)
    pos = np.array([s.q[:3] for s in out])
    vel = np.array([s.v[:3] for s in out])
    t = np.array([tick.t_s for tick in g1_quiet.ticks])
    switches = [np.searchsorted(t, ts - 1e-9) for ts in (0.8, 1.2, 1.8, 2.2)]
    for k in switches:
        window = slice(k - 1, k + 3)
        assert 1e3 * np.abs(np.diff(pos[window], axis=0)).max() < 0.5  # mm per tick
        assert np.abs(np.diff(vel[window], axis=0)).max() < 0.02
    # Per-tick motion at the switches is no larger than elsewhere.
    steps = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    assert max(steps[k - 1:k + 2].max() for k in switches) < 3.0 * np.percentile(steps, 99) + 1e-5
    # With one foot flagged, the estimate stays close to the all-stance one and to the truth.
    ref_pos = np.array([s.q[:3] for s in ref])
    assert 1e3 * np.abs(pos - ref_pos).max() < 3.0
    assert np.degrees(np.abs(e["rpy"][:, :2])).max() < 1.0
    assert 1e3 * np.abs(e["pos"][:, 2]).max() < 10.0
    assert est.odometry.anchored.all()  # both restored


def test_kinematic_swing_with_the_base_moving_and_a_foot_in_the_air():
    """Exact synthetic data: the left sole stays flat on the ground while both legs move, so the
    base sways and tilts and the right foot lifts ~10 cm (flagged as swing), then everything returns."""
    robot = load_robot("g1")
    model, data = robot.pin_model, robot.pin_model.createData()
    q0 = robot.q_standing.copy()
    left, right = robot.frame_id("left_foot"), robot.frame_id("right_foot")
    pin.framesForwardKinematics(model, data, q0)
    left_world = data.oMf[left].copy()
    motion = [("left_hip_pitch_joint", -0.15), ("left_knee_joint", 0.3), ("left_ankle_pitch_joint", -0.12),
              ("left_hip_roll_joint", 0.05), ("left_ankle_roll_joint", -0.04),
              ("right_hip_pitch_joint", -0.4), ("right_knee_joint", 0.7), ("right_ankle_pitch_joint", -0.2)]
    index = [robot.joint_names.index(n) for n, _ in motion]
    amp = np.array([a for _, a in motion])

    def joints(t_s: float) -> tuple[np.ndarray, np.ndarray]:
        jq, jqd = q0[7:].copy(), np.zeros(robot.n_joints)
        if 0.5 < t_s < 1.5:
            x = math.pi * (t_s - 0.5)
            jq[index] += amp * math.sin(x) ** 2
            jqd[index] = amp * math.pi * math.sin(2 * x)
        return jq, jqd

    def base(t_s: float) -> pin.SE3:
        q = q0.copy()
        q[:7] = [0, 0, 0, 0, 0, 0, 1]
        q[7:] = joints(t_s)[0]
        pin.framesForwardKinematics(model, data, q)
        return left_world * data.oMf[left].inverse()

    rng = np.random.default_rng(3)
    est = StateEstimator(robot)
    h = 1e-4
    worst = {"rpy": 0.0, "pos": 0.0}
    vel_err, positions, swing_height = [], [], 0.0
    for k in range(1, 1001):
        t_s = k * DT_S
        m, mp, mm = base(t_s), base(t_s + h), base(t_s - h)
        v_w = (mp.translation - mm.translation) / (2 * h)
        a_w = (mp.translation - 2 * m.translation + mm.translation) / h ** 2
        w_b = pin.log3(mm.rotation.T @ mp.rotation) / (2 * h)
        jq, jqd = joints(t_s)
        truth = RobotState(t_s, np.r_[m.translation, pin.Quaternion(m.rotation).coeffs(), jq],
                           np.r_[m.rotation.T @ v_w, w_b, jqd])
        if k == 1:
            est.reset(truth)
        imu = ImuSample(w_b + rng.normal(0, 3e-4 / math.sqrt(DT_S), 3),
                        m.rotation.T @ (a_w + [0.0, 0.0, GRAVITY_MPS2]) + rng.normal(0, 2e-3 / math.sqrt(DT_S), 3))
        contact = np.array([True, not (0.47 <= t_s < 1.53)])
        s = est.update(t_s, imu, jq + rng.normal(0, ENCODER_STD_RAD, robot.n_joints),
                       jqd + rng.normal(0, ENCODER_RATE_STD_RADPS, robot.n_joints), contact)
        e = errors(s, truth)
        worst["rpy"] = max(worst["rpy"], float(np.abs(e["rpy"][:2]).max()))
        worst["pos"] = max(worst["pos"], float(np.abs(e["pos"]).max()))
        vel_err.append(e["vel"])
        positions.append(s.q[:3])
        pin.framesForwardKinematics(model, data, truth.q)
        swing_height = max(swing_height, float(data.oMf[right].translation[2]))
    assert swing_height > 0.05  # the right foot really was in the air
    assert math.degrees(worst["rpy"]) < 1.0
    assert worst["pos"] < 0.01
    assert np.sqrt(np.mean(np.array(vel_err) ** 2, axis=0)).max() < 0.02
    steps = np.linalg.norm(np.diff(np.array(positions), axis=0), axis=1)
    for t_switch in (0.47, 1.53):
        k = int(round(t_switch / DT_S))
        assert steps[k - 3:k + 2].max() < 5e-4  # base moves ≤ 0.16 m/s: ≤ 0.3 mm per tick


def test_a_flagged_foot_far_above_the_ground_is_not_used(g1_quiet):
    robot = load_robot("g1")
    est = StateEstimator(robot)
    est.reset(g1_quiet.init)
    lifted = None
    for tick in g1_quiet.ticks[:200]:
        q = tick.joint_q.copy()
        # Pretend the left leg is folded up (knee bent) while the planner still flags it in stance.
        q[robot.joint_names.index("left_knee_joint")] += 1.2
        s = est.update(tick.t_s, tick.imu, q, tick.joint_qd, np.ones(2, dtype=bool))
        lifted = est.odometry.anchored.copy()
    assert lifted is not None and not lifted[0] and lifted[1]
    assert 1e3 * abs(s.q[2] - g1_quiet.ticks[199].truth.q[2]) < 10.0


# ----------------------------------------------------------------------------- (4) truth mode


def test_truth_mode_returns_exactly_the_truth(g1_quiet):
    est = StateEstimator(load_robot("g1"), mode="truth")
    est.reset(g1_quiet.init)
    for tick in g1_quiet.ticks[:50]:
        s = est.update(tick.t_s, tick.imu, tick.joint_q, tick.joint_qd, np.ones(2, dtype=bool), truth=tick.truth)
        assert s.t_s == tick.truth.t_s
        assert np.array_equal(s.q, tick.truth.q) and np.array_equal(s.v, tick.truth.v)
        assert s.q is not tick.truth.q  # a copy: the controller may not alias the simulator's state
    s.q[:] = 0.0
    assert np.linalg.norm(g1_quiet.ticks[49].truth.q) > 0.0
    with pytest.raises(ValueError):
        est.update(0.0, None, g1_quiet.ticks[0].joint_q, g1_quiet.ticks[0].joint_qd, np.ones(2, dtype=bool))
    with pytest.raises(ValueError):
        StateEstimator(load_robot("g1"), mode="oracle")


# ----------------------------------------------------------------------------- (5) garbage


@pytest.mark.parametrize("garbage", [
    ImuSample(np.array([np.nan, 0.0, 0.0]), np.array([0.0, 0.0, 9.81])),
    ImuSample(np.array([0.0, 0.0, 0.0]), np.array([0.0, np.inf, 9.81])),
    ImuSample(np.array([0.0, 1e6, 0.0]), np.array([0.0, 0.0, 9.81])),
    ImuSample(np.array([0.0, 0.0]), np.array([0.0, 0.0, 9.81])),
])
def test_garbage_imu_sample_is_treated_as_a_missing_one(g1_quiet, garbage):
    robot = load_robot("g1")
    with_garbage, with_none = StateEstimator(robot), StateEstimator(robot)
    with_garbage.reset(g1_quiet.init)
    with_none.reset(g1_quiet.init)
    contact = np.ones(2, dtype=bool)
    bad_ticks = set(range(300, 310)) | {400}
    for k, tick in enumerate(g1_quiet.ticks[:600]):
        a = with_garbage.update(tick.t_s, garbage if k in bad_ticks else tick.imu, tick.joint_q, tick.joint_qd, contact)
        b = with_none.update(tick.t_s, None if k in bad_ticks else tick.imu, tick.joint_q, tick.joint_qd, contact)
        assert np.all(np.isfinite(a.q)) and np.all(np.isfinite(a.v))
        assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v)
    assert with_garbage.rejected_imu_samples == len(bad_ticks)
    e = errors(a, g1_quiet.ticks[599].truth)
    assert np.degrees(np.abs(e["rpy"][:2])).max() < 1.0 and 1e3 * np.abs(e["pos"]).max() < 15.0


def test_garbage_encoders_and_timestamps_do_not_corrupt_the_state(g1_quiet):
    robot = load_robot("g1")
    est = StateEstimator(robot)
    est.reset(g1_quiet.init)
    contact = np.ones(2, dtype=bool)
    for k, tick in enumerate(g1_quiet.ticks[:600]):
        q, qd, t_s = tick.joint_q.copy(), tick.joint_qd.copy(), tick.t_s
        if k in (300, 301):
            q[3] = np.nan
            qd[5] = np.inf
        if k == 350:
            t_s = math.nan
        if k == 360:
            t_s -= 0.5  # out of order: not integrated
        s = est.update(t_s, tick.imu, q, qd, contact)
        assert np.all(np.isfinite(s.q)) and np.all(np.isfinite(s.v))
        if k in (300, 301):
            assert s.q[7 + 3] == pytest.approx(g1_quiet.ticks[299].joint_q[3])
    assert est.rejected_joint_samples == 2 and est.clock_resyncs == 0
    e = errors(s, g1_quiet.ticks[599].truth)
    assert np.degrees(np.abs(e["rpy"][:2])).max() < 1.0 and 1e3 * np.abs(e["pos"]).max() < 15.0
    # A clock that restarts (simulation reset without estimator reset) is re-synchronised.
    for tick in g1_quiet.ticks[:10]:
        s = est.update(tick.t_s, tick.imu, tick.joint_q, tick.joint_qd, contact)
    assert est.clock_resyncs == 1 and s.t_s == g1_quiet.ticks[9].t_s
    with pytest.raises(ValueError):
        est.update(2.0, None, np.zeros(3), np.zeros(3), contact)
    with pytest.raises(ValueError):
        est.update(2.0, None, g1_quiet.ticks[0].joint_q, g1_quiet.ticks[0].joint_qd, np.ones(3, dtype=bool))


# ----------------------------------------------------------------------------- building blocks


def test_reset_without_a_state_starts_on_the_ground(g1_quiet):
    est = StateEstimator(load_robot("g1"))
    est.reset(None)
    for tick in g1_quiet.ticks[:300]:
        s = est.update(tick.t_s, tick.imu, tick.joint_q, tick.joint_qd, np.ones(2, dtype=bool))
    truth = g1_quiet.ticks[299].truth
    assert abs(s.q[2] - truth.q[2]) < 0.005
    assert np.abs(s.q[:2] - (truth.q[:2] - g1_quiet.init.q[:2])).max() < 0.01
    assert np.degrees(np.abs(errors(s, truth)["rpy"][:2])).max() < 1.0


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6), st.integers(1, 3))
def test_closed_form_inverse_matches_numpy(values, m):
    a = np.array(values[: m * 2]).reshape(m, 2)
    s = a @ a.T + np.eye(m) * 0.1
    assert np.allclose(np.array(_inv_sym(s.tolist())), np.linalg.inv(s), rtol=1e-9, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3))
def test_sole_contact_point_is_the_softmin_of_its_corners(roll, pitch):
    robot = load_robot("g1")
    kin = LegKinematics(robot, softmin_m=0.004)
    q = robot.q_standing.copy()
    q[3:7] = pin.Quaternion(pin.rpy.rpyToMatrix(roll, pitch, 0.3)).coeffs()
    feet = kin.compute(q[7:], np.zeros(robot.n_joints), np.roll(q[3:7], 1))  # attitude in w, x, y, z
    data = robot.pin_model.createData()
    q_base = q.copy()
    q_base[:3] = 0.0
    pin.framesForwardKinematics(robot.pin_model, data, q_base)
    for i, side in enumerate(("left", "right")):
        corners = np.array([data.oMf[robot.frame_id(f"{side}_foot_c{c}")].translation for c in range(4)])
        w = np.exp(-(corners[:, 2] - corners[:, 2].min()) / 0.004)
        expected = (w @ corners) / w.sum()
        assert np.allclose(feet.point_w_m[i], expected, atol=1e-9)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4).filter(lambda c: np.linalg.norm(c) > 0.1),
       st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3))
def test_quaternion_step_matches_pinocchio(coeffs, rotvec):
    q = np.array(coeffs) / np.linalg.norm(coeffs)
    stepped = np.array(_quat_step(tuple(q), *rotvec))  # w, x, y, z (pinocchio's Quaternion takes x, y, z, w)
    expected = pin.Quaternion(np.roll(q, -1)).toRotationMatrix() @ pin.exp3(np.array(rotvec))
    assert np.allclose(pin.Quaternion(np.roll(stepped, -1)).toRotationMatrix(), expected, atol=1e-12)
    assert abs(np.linalg.norm(stepped) - 1.0) < 1e-12


def test_mujoco_imu_reads_the_base_frame_and_seeds_its_noise():
    robot = load_robot("g1")
    sim = Simulation(robot)
    for _ in range(299):
        sim.step()
    before = sim.state()
    sim.step()
    clean = MujocoImu(robot.mj_model).read(sim.data)
    up_b = pin.Quaternion(sim.state().q[3:7]).toRotationMatrix()[2]
    assert np.allclose(clean.accel_mps2, GRAVITY_MPS2 * up_b, atol=0.05)  # at rest: +g along "up"
    # Sensors are evaluated inside mj_step before integration: they describe the previous tick.
    assert np.allclose(clean.gyro_radps, before.v[3:6], atol=1e-12)
    assert np.allclose(MujocoImu(robot.mj_model).truth_quat_wxyz(sim.data), np.roll(before.q[3:7], 1), atol=1e-12)
    a, b = (MujocoImu(robot.mj_model, REALISTIC_IMU, seed=5).read(sim.data) for _ in range(2))
    assert np.array_equal(a.gyro_radps, b.gyro_radps) and np.array_equal(a.accel_mps2, b.accel_mps2)
    noisy = [MujocoImu(robot.mj_model, REALISTIC_IMU, seed=s).read(sim.data) for s in range(200)]
    mean_gyro_error = np.mean([n.gyro_radps - clean.gyro_radps for n in noisy], axis=0)
    assert np.allclose(mean_gyro_error, REALISTIC_IMU.gyro_bias_radps, atol=2e-3)


def test_update_benchmark_runs():
    """The cost itself is a figure of `studio bench estimator`, not a test assertion (machine speed)."""
    result = benchmark_estimator("g1", n_ticks=100)
    assert 0 < result["median_us"] <= result["p99_us"] and all(np.isfinite(v) for v in result.values()
                                                               if isinstance(v, float))
