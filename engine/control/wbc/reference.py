"""What the whole-body controller tracks and reports: gains and weights (``WbcGains``), the reference of
one tick (``WbcReference``), the diagnostics of a solve, and the friction pyramid of Eq. 17."""

from __future__ import annotations

import dataclasses
import difflib
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from engine.constants import SIDES
from engine.robot.config import RobotConfigError
from engine.robot.model import RobotModel
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from engine.control.controller import JointCommand, RobotState
    from engine.control.wbc.qp import CentroidalQp

FloatArray = NDArray[np.float64]
N_CORNERS = 4  # per sole
N_BASIS = 4  # friction-pyramid edges per corner


# ----------------------------------------------------------------------------- parameters


@dataclass
class WbcGains:
    """Feedback gains (1/s², 1/s), task weights and QP parameters of the whole-body controller."""

    # Horizontal CoM (x, y) PD on the MPC reference; vertical CoM is left to the pelvis task.
    com_kp: float = 40.0
    com_kd: float = 12.0
    com_weight: float = 100.0
    com_z_weight: float = 0.0
    # Pelvis height and orientation.
    pelvis_height_kp: float = 100.0
    pelvis_height_kd: float = 20.0
    pelvis_height_weight: float = 100.0
    pelvis_rot_kp: float = 150.0
    pelvis_rot_kd: float = 25.0
    pelvis_rot_weight: float = 10.0
    # Feet: swing tracking (PD on the planner's pose) and contact (hold still, damping only).
    swing_foot_kp: float = 400.0
    swing_foot_kd: float = 40.0
    swing_foot_weight: float = 50.0
    # ... of the swing foot's orientation rows (its style's heel/toe pitch, roll, yaw): near an ankle
    # limit only the rest of the body can turn the foot further, at the cost of the CoM (issue 13).
    swing_foot_rotation_weight: float = 50.0
    contact_foot_kd: float = 20.0
    contact_foot_weight: float = 1000.0
    # Upper-body joints.
    upper_body_kp: float = 150.0
    upper_body_kd: float = 25.0
    upper_body_weight: float = 1.0
    # Centroidal angular momentum damping.
    angular_momentum_kd: float = 5.0
    angular_momentum_weight: float = 0.3
    # Regularisation (Eq. 20).
    lambda_qdd: float = 1e-4
    lambda_rho: float = 1e-5
    lambda_tau: float = 1e-6
    # Contact model (Eqs. 17, 24, 25).
    friction_mu: float = 0.7
    max_corner_force_weights: float = 2.0  # ρ ≤ this × m g per basis weight
    # Soft joint limits (Eqs. 22, 23) and acceleration limits.
    joint_limit_kl: float = 400.0
    joint_limit_bl: float = 40.0
    max_joint_acc_radps2: float = 400.0
    # Actuator torque limits (the URDF's efforts), kept with headroom for the servo's PD terms.
    torque_limit_fraction: float = 0.9
    # Joint set-points: integrated q̈, clipped to a max error from the measured state.
    servo_kp_scale: float = 0.25
    servo_kd_scale: float = 0.5
    max_position_error_rad: float = 0.01
    max_velocity_error_radps: float = 0.2
    # Fallback: stiff PD hold; the last good feed-forward decays with this time constant.
    fallback_decay_s: float = 0.2
    # Task priority (engine/control/wbc/priority.py, issue 13). Level 1: the feet on the ground, the swing
    # foot's position, the pelvis height and the CoM; level 2: the style's tasks (swing foot orientation,
    # pelvis orientation, upper body) and the angular-momentum damping. A finite slack (m/s², rad/s²) solves two QPs per tick: level 1 first, then
    # level 2 with level 1's task accelerations held within the slack of the first solve's. inf: one QP
    # weighing every task against every other (as before).
    priority_slack_mps2: float = math.inf
    # Level 2's weights × this (1: as before; < 1: a weighted hierarchy in the one QP).
    priority_level2_scale: float = 1.0

    @classmethod
    def for_robot(cls, robot: RobotModel) -> WbcGains:
        """The defaults with the robot's ``[control.wbc]`` overrides from ``robots/<name>.toml``
        (tuned in closed loop in MuJoCo). An unknown field is a config error naming the file and field."""
        overrides = dict(getattr(robot.config, "wbc_gains", {}) or {})
        known = {f.name for f in dataclasses.fields(cls)}
        for key in overrides:
            if key not in known:
                close = difflib.get_close_matches(key, sorted(known), n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise RobotConfigError(f"{robot.config.path.name}: control.wbc.{key}: unknown WbcGains field{hint}")
        return cls(**overrides)


@dataclass
class WbcReference:
    """What the whole-body controller tracks at one tick. World frame, SI units.

    Feet are ordered (left, right); contact corners in each foot's order front-left,
    front-right, back-right, back-left. Upper-body joints follow the order given to
    :class:`TaskSpaceInverseDynamics`.
    """

    com_xy_m: FloatArray  # (2,) from the CoM MPC
    com_xy_vel_mps: FloatArray  # (2,)
    com_xy_acc_mps2: FloatArray  # (2,)
    pelvis_height_m: float
    pelvis_height_rate_mps: float
    pelvis_rotation: FloatArray  # (3, 3) world ← pelvis
    pelvis_ang_vel_radps: FloatArray  # (3,)
    foot_pos_m: FloatArray  # (2, 3) sole centres
    foot_rotation: FloatArray  # (2, 3, 3)
    foot_lin_vel_mps: FloatArray  # (2, 3)
    foot_ang_vel_radps: FloatArray  # (2, 3)
    contact: NDArray[np.bool_]  # (2, 4) active sole corners
    upper_body_q_rad: FloatArray  # (n_upper,)
    upper_body_qd_radps: FloatArray  # (n_upper,)
    external_wrench: FloatArray | None = None  # (6,) [force N; torque N·m about the CoM] estimate
    foot_lin_acc_mps2: FloatArray | None = None  # (2, 3) swing feed-forward
    foot_ang_acc_radps2: FloatArray | None = None  # (2, 3)
    com_z_m: float | None = None  # tracked only when gains.com_z_weight > 0

    def is_finite(self) -> bool:
        """Every number finite (a sum propagates NaN/inf); malformed values count as not finite."""
        arrays = (self.com_xy_m, self.com_xy_vel_mps, self.com_xy_acc_mps2, self.pelvis_rotation,
                  self.pelvis_ang_vel_radps, self.foot_pos_m, self.foot_rotation, self.foot_lin_vel_mps,
                  self.foot_ang_vel_radps, self.upper_body_q_rad, self.upper_body_qd_radps, self.pelvis_height_m,
                  self.pelvis_height_rate_mps, self.external_wrench, self.foot_lin_acc_mps2, self.foot_ang_acc_radps2,
                  self.com_z_m)
        try:
            flat = np.concatenate([a for a in arrays if a is not None], axis=None, dtype=float)
            return math.isfinite(float(flat.sum()))
        except (TypeError, ValueError):
            return False


@dataclass
class WbcDiagnostics:
    """The solution of one tick and how it was obtained (contact forces, CoP and the QP residual
    are derived on first access, so the control loop does not pay for them)."""

    status: str  # "solved", "solved_inaccurate" or "fallback_<reason>"
    message: str = ""
    backend: str = ""  # "active_set", "daqp", "dense", "osqp" or "placo"
    qdd: FloatArray | None = None  # (nv,)
    rho: FloatArray | None = None  # (32,) friction-basis weights
    tau_nm: FloatArray | None = None  # (n_joints,) Eq. 15
    qp_iterations: int = 0
    pinocchio_s: float = 0.0
    build_s: float = 0.0
    qp_s: float = 0.0
    total_s: float = 0.0
    basis: FloatArray | None = field(default=None, repr=False)  # (2, 3, 4) pyramid edges per foot
    corners_m: FloatArray | None = field(default=None, repr=False)  # (2, 3, 4) corner positions
    qp: CentroidalQp | None = field(default=None, repr=False)
    # (2,) Σ of the solution's horizontal contact forces, when the solver computed it (the compiled kernels)
    horizontal_force_n: FloatArray | None = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        return self.status.startswith("solved")

    @cached_property
    def contact_forces_n(self) -> FloatArray | None:
        """(2, 4, 3) world force at each sole corner, f_c = B_c ρ_c (Eq. 17)."""
        if self.rho is None or self.basis is None:
            return None
        return np.einsum("fkb,fcb->fck", self.basis, self.rho.reshape(len(SIDES), N_CORNERS, N_BASIS))

    @cached_property
    def cop_m(self) -> FloatArray | None:
        """(2,) centre of pressure of the solution's contact forces (NaN without normal force)."""
        forces = self.contact_forces_n
        if forces is None or self.corners_m is None:
            return None
        fz = forces[..., 2]
        total = float(fz.sum())
        if total <= 1e-6:
            return np.full(2, np.nan)
        return (self.corners_m[:, :2] * fz[:, None, :]).sum(axis=(0, 2)) / total

    @cached_property
    def centroidal_residual(self) -> float:
        """max |Eq. 21| of the solution (after the exact base-acceleration projection)."""
        if self.qp is None or self.qdd is None or self.rho is None:
            return math.nan
        return self.qp.equality_residual(self.qdd, self.rho)


class WholeBodyController(Protocol):
    """What the walking controller needs of a whole-body controller: the paper's
    :class:`~engine.control.wbc.TaskSpaceInverseDynamics` and placo's peer both provide it."""

    diagnostics: WbcDiagnostics

    def reset(self, state: RobotState) -> None: ...

    def compute(self, state: RobotState, ref: WbcReference) -> JointCommand: ...


def friction_basis(normal: FloatArray, tangent: FloatArray, mu: float) -> FloatArray:
    """(3, 4) unit edges ``(n ± μ t1, n ± μ t2)/√(1+μ²)`` of a pyramid inside the friction cone (Eq. 17)."""
    n = normal / np.linalg.norm(normal)
    t1 = tangent - (tangent @ n) * n
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    edges = np.stack([n + mu * t1, n - mu * t1, n + mu * t2, n - mu * t2], axis=1)
    return edges / math.sqrt(1.0 + mu * mu)
