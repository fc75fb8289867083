"""MuJoCo simulation of one robot: stepping, joint servos, pushes, fall detection, poses."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from engine.constants import CONTROL_PERIOD_S  # noqa: F401 - re-exported: the control tick
from engine.control.controller import Controller, JointCommand, RobotState, StandingPdController
from engine.control.static_balance import static_contact_torques
from engine.robot.model import RobotModel

if TYPE_CHECKING:
    from engine.imu import ImuNoise, MujocoImu

FALL_HEIGHT_FRACTION = 0.55  # base below this fraction of its standing height → fallen
FALL_TILT_RAD = 1.0  # base tilted more than this from upright → fallen


@dataclass
class Push:
    """An external force on a body for a while (world frame, N)."""

    force_n: np.ndarray
    start_s: float
    duration_s: float
    body_id: int


def _finite_sum(x: np.ndarray) -> bool:
    """``math.isfinite(x.sum())``: Σ x² is cheaper and finite only when every |x| < 1.3e154, and then so
    is the sum (the sum is taken only when Σ x² is not finite)."""
    return math.isfinite(x.dot(x)) or math.isfinite(float(x.sum()))


def standing_controller(robot: RobotModel) -> StandingPdController:
    """Joint PD on the standing pose with static-balance feed-forward torques."""
    tau = static_contact_torques(robot, robot.q_standing)
    return StandingPdController(robot.q_standing[7:], robot.kp, robot.kd, tau)


class Simulation:
    """Steps the MuJoCo model of ``robot`` under a :class:`Controller`."""

    def __init__(self, robot: RobotModel, controller: Controller | None = None):
        if not robot.config.simulated:
            raise ValueError(f"{robot.name} is a {robot.kind}: it is not simulated")
        self.robot = robot
        self.model = robot.mj_model
        self.data = mujoco.MjData(self.model)
        self.controller: Controller = controller or standing_controller(robot)
        self.pushes: list[Push] = []
        self.command: JointCommand | None = None
        self.root_body_id = self.model.body(robot.config.root_link).id
        self.standing_base_z = float(robot.q_standing[2])
        self.fallen = False
        self.imu: MujocoImu | None = None
        # The servos' torque bounds, and where their torques go in data.ctrl (a slice when in order).
        self._effort_limits = np.asarray(robot.effort_limits, dtype=float)
        self._neg_effort_limits = -self._effort_limits
        act = np.asarray(robot.mj_actuator_index)
        self._ctrl_index: slice | np.ndarray = (
            slice(0, act.size) if np.array_equal(act, np.arange(act.size)) else act)
        self.reset()

    # ------------------------------------------------------------------ state
    @property
    def time_s(self) -> float:
        return float(self.data.time)

    def state(self) -> RobotState:
        q = self.robot.pin_q_from_mj(self.data.qpos)
        v = self.robot.pin_v_from_mj(self.data.qvel, self.data.qpos)
        return RobotState(self.time_s, q, v)

    def joint_positions(self) -> np.ndarray:
        return self.data.qpos[self.robot.mj_qpos_index]  # a gather: already a copy

    def joint_velocities(self) -> np.ndarray:
        return self.data.qvel[self.robot.mj_dof_index]

    def body_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """World positions (B,3) and wxyz quaternions (B,4) of every body but the world."""
        return self.data.xpos[1:].copy(), self.data.xquat[1:].copy()

    # ------------------------------------------------------------------ control
    def reset(self, qpos: np.ndarray | None = None) -> None:
        mujoco.mj_resetData(self.model, self.data)
        self._pushed = True  # clear any applied force on the next tick
        self.data.qpos[:] = self.robot.mj_standing_qpos() if qpos is None else qpos
        self.data.qvel[:] = 0.0
        mujoco.mj_forward(self.model, self.data)
        self.pushes.clear()
        self.fallen = False
        self.controller.reset(self.state())
        self.command = None

    def set_controller(self, controller: Controller) -> None:
        self.controller = controller
        controller.reset(self.state())

    def push(self, force_n: np.ndarray, duration_s: float, body: str | None = None) -> None:
        body_id = self.root_body_id if body is None else self.model.body(body).id
        self.pushes.append(Push(np.asarray(force_n, dtype=float), self.time_s, float(duration_s), body_id))

    def enable_imu(self, noise: ImuNoise | None = None, seed: int = 0) -> None:
        """Attach the simulated IMU: controllers then receive ``state.imu`` samples."""
        from engine.imu import ImuNoise, MujocoImu

        self.imu = MujocoImu(self.model, noise=noise if noise is not None else ImuNoise(), seed=seed)

    def step(self) -> None:
        """One control tick: controller → joint servos → one physics step."""
        state = self.state()
        # The servos measure the joints the controller is handed (the same tick, read once);
        # copies, so that a controller writing into its state cannot move them.
        joint_q, joint_qd = state.q[7:].copy(), state.v[6:].copy()
        if self.imu is not None:
            state.imu = self.imu.read(self.data)
        self.command = self.controller.compute(state)
        self._apply_servos(self.command, joint_q, joint_qd)
        self._apply_pushes()
        mujoco.mj_step(self.model, self.data)
        if not self.fallen:
            self.fallen = self.detect_fall()

    def _apply_servos(self, cmd: JointCommand, joint_q: np.ndarray | None = None,
                      joint_qd: np.ndarray | None = None) -> None:
        """PD + feed-forward torques on the measured joints (read now unless given), clipped to the
        effort limits; all zero when any is not finite."""
        q = self.joint_positions() if joint_q is None else joint_q
        qd = self.joint_velocities() if joint_qd is None else joint_qd
        tau = cmd.torque(q, qd, self._effort_limits, self._neg_effort_limits)
        # Σ τ² is finite when every τ is (the clipped torques cannot overflow it unless the limits
        # are huge): only then is the element-wise check needed.
        if not math.isfinite(tau.dot(tau)) and not np.isfinite(tau).all():
            tau = np.zeros_like(tau)
        self.data.ctrl[self._ctrl_index] = tau

    def _apply_pushes(self) -> None:
        if not self.pushes and not self._pushed:
            return  # nothing applied last tick, nothing to apply now
        self.data.xfrc_applied[:] = 0.0
        t = self.time_s
        self.pushes = [p for p in self.pushes if t < p.start_s + p.duration_s]
        for p in self.pushes:
            self.data.xfrc_applied[p.body_id, 0:3] += p.force_n
        self._pushed = bool(self.pushes)

    def detect_fall(self) -> bool:
        qpos = self.data.qpos
        z, _, qx, qy = qpos[2:6].tolist()
        # Tilt: angle between the base z axis and world z.
        up_z = 1.0 - 2.0 * (qx * qx + qy * qy)
        tilt = math.acos(min(max(up_z, -1.0), 1.0)) if math.isfinite(up_z) else math.inf
        return bool(z < FALL_HEIGHT_FRACTION * self.standing_base_z or tilt > FALL_TILT_RAD
                    or not _finite_sum(qpos))
