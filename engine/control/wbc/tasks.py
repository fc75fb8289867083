"""Acceleration-level tasks of the task-space inverse dynamics (paper Appendix "ID", Eq. 18).

Each task is one least-squares objective on the joint accelerations q̈ (pinocchio ``nv``
order)::

    w ⊙ (J q̈ + J̇ q̇ − a*)² ,   a* = a_ff + kp ⊙ e + kd ⊙ ė

with ``e``/``ė`` the task error/error rate against the reference (position, velocity,
feed-forward acceleration). In the style of mink, every task has one concept and three
typed methods: :meth:`Task.compute_jacobian` (J), :meth:`Task.compute_drift` (J̇ q̇) and
:meth:`Task.compute_desired_acceleration` (a*). They read a :class:`DynamicsSnapshot`:
the pinocchio quantities of the current state, computed once per control tick.

Frames: everything is world-aligned (pinocchio ``LOCAL_WORLD_ALIGNED``); orientation
errors are ``log3(R* Rᵀ)`` (world axes); accelerations of frame origins are classical
(``J̇ q̇`` includes ω × v).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypeAlias

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
#: A per-row gain or weight: one value for every row, or one per row.
Gain: TypeAlias = "float | Sequence[float] | FloatArray"

__all__ = [
    "AngularMomentumTask",
    "ComTask",
    "DynamicsSnapshot",
    "FramePoseTask",
    "JointTask",
    "PelvisTask",
    "Task",
]


_ZEROS: dict[int, FloatArray] = {}  # q̈ = 0 per model size (read-only, shared)


@dataclass
class DynamicsSnapshot:
    """Pinocchio quantities of one state, shared by every task and the ID solver.

    ``frame_*`` hold the tracked frames (the feet) in the order given to :meth:`compute`.
    """

    q: FloatArray
    v: FloatArray
    mass_matrix: FloatArray  # (nv, nv), armature included
    nonlinear_effects: FloatArray  # (nv,) Coriolis, centrifugal and gravity
    centroidal_map: FloatArray  # (6, nv) A_h, momentum about the CoM, [linear; angular]
    centroidal_drift: FloatArray  # (6,) Ȧ_h q̇
    momentum: FloatArray  # (6,) h = A_h q̇
    com_m: FloatArray  # (3,)
    mass_kg: float
    base_rotation: FloatArray  # (3, 3) world ← base
    frame_position_m: FloatArray  # (F, 3)
    frame_rotation: FloatArray  # (F, 3, 3)
    frame_jacobian: FloatArray  # (F, 6, nv) LOCAL_WORLD_ALIGNED, [linear; angular]
    frame_velocity: FloatArray  # (F, 6) [linear m/s; angular rad/s], world axes
    frame_drift: FloatArray  # (F, 6) classical J̇ q̇, world axes

    @property
    def com_velocity_mps(self) -> FloatArray:
        return self.momentum[:3] / self.mass_kg

    @classmethod
    def compute(cls, model: pin.Model, data: pin.Data, q: FloatArray, v: FloatArray,
                frame_ids: list[int]) -> DynamicsSnapshot:
        """Four pinocchio passes (~20 µs for G1): CRBA (M, and the joint Jacobians ``data.J``: pinocchio 3's
        CRBA in the WORLD convention fills them, so no separate ``computeJointJacobians``), non-linear
        effects, CCRBA (A_h, h, CoM) and the centroidal momentum rate at q̈ = 0 (Ȧ_h q̇, and the
        frame acceleration drifts from the same forward pass)."""
        # (the bindings return owned copies of data.M, data.nle and data.Ag: no second copy)
        mass_matrix = pin.crba(model, data, q)
        nonlinear_effects = pin.nonLinearEffects(model, data, q, v)
        centroidal_map = pin.ccrba(model, data, q, v)
        zeros = _ZEROS.get(model.nv)
        if zeros is None:
            zeros = _ZEROS[model.nv] = np.zeros(model.nv)
            zeros.flags.writeable = False
        centroidal_drift = pin.computeCentroidalMomentumTimeVariation(model, data, q, v, zeros).vector.copy()
        n = len(frame_ids)
        pos = np.empty((n, 3))
        rot = np.empty((n, 3, 3))
        jac = np.empty((n, 6, model.nv))
        drift = np.empty((n, 6))
        lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        for i, fid in enumerate(frame_ids):
            placement = pin.updateFramePlacement(model, data, fid)
            pos[i] = placement.translation
            rot[i] = placement.rotation
            jac[i] = pin.getFrameJacobian(model, data, fid, lwa)
            drift[i] = pin.getFrameClassicalAcceleration(model, data, fid, lwa).vector
        return cls(
            q=q, v=v, mass_matrix=mass_matrix, nonlinear_effects=nonlinear_effects, centroidal_map=centroidal_map,
            centroidal_drift=centroidal_drift, momentum=data.hg.vector.copy(), com_m=data.com[0].copy(),
            mass_kg=float(data.mass[0]), base_rotation=data.oMi[1].rotation.copy(),
            frame_position_m=pos, frame_rotation=rot, frame_jacobian=jac, frame_velocity=jac @ v, frame_drift=drift,
        )


class Task(ABC):
    """One acceleration objective ``w ⊙ (J q̈ + J̇ q̇ − a*)²`` with PD feedback gains."""

    dim: int
    constant_jacobian: bool = False  # J never changes (the solver may copy it once)

    def __init__(self, dim: int, kp: Gain, kd: Gain, weight: Gain):
        self.dim = dim
        self.kp = np.broadcast_to(np.asarray(kp, dtype=float), (dim,)).copy()
        self.kd = np.broadcast_to(np.asarray(kd, dtype=float), (dim,)).copy()
        self.weight = np.broadcast_to(np.asarray(weight, dtype=float), (dim,)).copy()

    @abstractmethod
    def compute_jacobian(self, snap: DynamicsSnapshot) -> FloatArray:
        """J (dim, nv)."""

    @abstractmethod
    def compute_drift(self, snap: DynamicsSnapshot) -> FloatArray:
        """J̇ q̇ (dim,)."""

    @abstractmethod
    def compute_desired_acceleration(self, snap: DynamicsSnapshot) -> FloatArray:
        """a* (dim,) = feed-forward + PD feedback on the reference."""

    def write_rows(self, snap: DynamicsSnapshot, jac_out: FloatArray | None, rhs_out: FloatArray) -> None:
        """The task's rows of the stacked least squares, written in place: J into ``jac_out``
        (skipped when None: a constant J already there) and a* − J̇ q̇ into ``rhs_out``. Tasks
        override it with the same numbers in fewer array operations (the 500 Hz loop's cost)."""
        if jac_out is not None:
            jac_out[:] = self.compute_jacobian(snap)
        np.subtract(self.compute_desired_acceleration(snap), self.compute_drift(snap), out=rhs_out)


class FramePoseTask(Task):
    """6-D pose of a frame (a foot sole): world position and orientation, [linear; angular]."""

    def __init__(self, frame_index: int, kp: Gain = 0.0, kd: Gain = 0.0, weight: Gain = 1.0):
        super().__init__(6, kp, kd, weight)
        self.frame_index = frame_index  # index into the snapshot's frames
        self.position_m = np.zeros(3)
        self.rotation = np.eye(3)
        self.velocity = np.zeros(6)  # [m/s; rad/s]
        self.acceleration = np.zeros(6)  # [m/s²; rad/s²]

    def set_target(self, position_m: FloatArray, rotation: FloatArray, linear_velocity_mps: FloatArray | None = None,
                   angular_velocity_radps: FloatArray | None = None, linear_acceleration_mps2: FloatArray | None = None,
                   angular_acceleration_radps2: FloatArray | None = None) -> None:
        self.position_m = np.asarray(position_m, dtype=float)
        self.rotation = np.asarray(rotation, dtype=float)
        self.velocity[:3] = 0.0 if linear_velocity_mps is None else linear_velocity_mps
        self.velocity[3:] = 0.0 if angular_velocity_radps is None else angular_velocity_radps
        self.acceleration[:3] = 0.0 if linear_acceleration_mps2 is None else linear_acceleration_mps2
        self.acceleration[3:] = 0.0 if angular_acceleration_radps2 is None else angular_acceleration_radps2

    def compute_error(self, snap: DynamicsSnapshot) -> FloatArray:
        """[p* − p; log3(R* Rᵀ)] in world axes."""
        i = self.frame_index
        err = np.empty(6)
        err[:3] = self.position_m - snap.frame_position_m[i]
        err[3:] = pin.log3(self.rotation @ snap.frame_rotation[i].T)
        return err

    def compute_jacobian(self, snap: DynamicsSnapshot) -> FloatArray:
        return snap.frame_jacobian[self.frame_index]

    def compute_drift(self, snap: DynamicsSnapshot) -> FloatArray:
        return snap.frame_drift[self.frame_index]

    def compute_desired_acceleration(self, snap: DynamicsSnapshot) -> FloatArray:
        rate = self.velocity - snap.frame_velocity[self.frame_index]
        if not self.kp.any():  # damping only (a foot held on the ground): no pose error needed
            return self.acceleration + self.kd * rate
        return self.acceleration + self.kp * self.compute_error(snap) + self.kd * rate


class PelvisTask(Task):
    """Pelvis (floating base) height and orientation: rows [z; ωx; ωy; ωz], world axes."""

    def __init__(self, kp: Gain = 0.0, kd: Gain = 0.0, weight: Gain = 1.0):
        super().__init__(4, kp, kd, weight)
        self.height_m = 0.0
        self.height_rate_mps = 0.0
        self.height_acceleration_mps2 = 0.0
        self.rotation = np.eye(3)
        self.angular_velocity_radps = np.zeros(3)
        self.angular_acceleration_radps2 = np.zeros(3)
        self._feedforward = np.zeros(4)
        self._jacobian: FloatArray | None = None

    def set_target(self, height_m: float, rotation: FloatArray, height_rate_mps: float = 0.0,
                   angular_velocity_radps: FloatArray | None = None, height_acceleration_mps2: float = 0.0,
                   angular_acceleration_radps2: FloatArray | None = None) -> None:
        self.height_m = float(height_m)
        self.height_rate_mps = float(height_rate_mps)
        self.height_acceleration_mps2 = float(height_acceleration_mps2)
        self.rotation = np.asarray(rotation, dtype=float)
        self.angular_velocity_radps = np.zeros(3) if angular_velocity_radps is None else np.asarray(angular_velocity_radps, float)
        self.angular_acceleration_radps2 = (np.zeros(3) if angular_acceleration_radps2 is None
                                            else np.asarray(angular_acceleration_radps2, float))
        self._feedforward = np.concatenate([[self.height_acceleration_mps2], self.angular_acceleration_radps2])

    def compute_jacobian(self, snap: DynamicsSnapshot) -> FloatArray:
        rot = snap.base_rotation
        jac = self._jacobian
        if jac is None or jac.shape[1] != snap.v.size:
            jac = self._jacobian = np.zeros((4, snap.v.size))
        jac[0, 0:3] = rot[2]  # ż = (R v_base)_z
        jac[1:4, 3:6] = rot  # ω_world = R ω_base
        return jac

    def compute_drift(self, snap: DynamicsSnapshot) -> FloatArray:
        (wx, wy, wz), (vx, vy, vz) = snap.v[3:6], snap.v[0:3]
        r = snap.base_rotation[2]  # (R (ω × v))_z, base-frame ω and v
        return np.array([r[0] * (wy * vz - wz * vy) + r[1] * (wz * vx - wx * vz) + r[2] * (wx * vy - wy * vx),
                         0.0, 0.0, 0.0])

    def write_rows(self, snap: DynamicsSnapshot, jac_out: FloatArray | None, rhs_out: FloatArray) -> None:
        rot = snap.base_rotation
        if jac_out is not None:  # only these blocks are non-zero (the rest stays zero in the stack)
            jac_out[0, 0:3] = rot[2]
            jac_out[1:4, 3:6] = rot
        rhs_out[:] = self.compute_desired_acceleration(snap)
        rhs_out[0] -= self.compute_drift(snap)[0]

    def compute_desired_acceleration(self, snap: DynamicsSnapshot) -> FloatArray:
        rot = snap.base_rotation
        out = self._feedforward.copy()
        v = snap.v
        height_rate = rot[2, 0] * v[0] + rot[2, 1] * v[1] + rot[2, 2] * v[2]
        out[0] += self.kp[0] * (self.height_m - snap.q[2]) + self.kd[0] * (self.height_rate_mps - height_rate)
        out[1:] += self.kp[1:] * pin.log3(self.rotation @ rot.T) + self.kd[1:] * (self.angular_velocity_radps - rot @ v[3:6])
        return out


class ComTask(Task):
    """Centre of mass position, rows [x; y; z] (z usually weighted 0 or lightly).

    J = A_h,lin / m and J̇ q̇ = (Ȧ_h q̇)_lin / m: the linear momentum rate over the mass.
    """

    def __init__(self, kp: Gain = 0.0, kd: Gain = 0.0, weight: Gain = 1.0):
        super().__init__(3, kp, kd, weight)
        self.position_m = np.zeros(3)
        self.velocity_mps = np.zeros(3)
        self.acceleration_mps2 = np.zeros(3)

    def set_target(self, position_m: FloatArray, velocity_mps: FloatArray | None = None,
                   acceleration_mps2: FloatArray | None = None) -> None:
        self.position_m = np.array(position_m, dtype=float)  # owned copies (targets may be written in place)
        self.velocity_mps = np.zeros(3) if velocity_mps is None else np.array(velocity_mps, dtype=float)
        self.acceleration_mps2 = np.zeros(3) if acceleration_mps2 is None else np.array(acceleration_mps2, dtype=float)

    def compute_jacobian(self, snap: DynamicsSnapshot) -> FloatArray:
        return snap.centroidal_map[:3] / snap.mass_kg

    def write_rows(self, snap: DynamicsSnapshot, jac_out: FloatArray | None, rhs_out: FloatArray) -> None:
        inv_m = 1.0 / snap.mass_kg
        if jac_out is not None:
            np.multiply(snap.centroidal_map[:3], inv_m, out=jac_out)
        lin = snap.momentum[:3] * inv_m
        rhs_out[:] = (self.acceleration_mps2 + self.kp * (self.position_m - snap.com_m)
                      + self.kd * (self.velocity_mps - lin) - snap.centroidal_drift[:3] * inv_m)

    def compute_drift(self, snap: DynamicsSnapshot) -> FloatArray:
        return snap.centroidal_drift[:3] / snap.mass_kg

    def compute_desired_acceleration(self, snap: DynamicsSnapshot) -> FloatArray:
        return (self.acceleration_mps2 + self.kp * (self.position_m - snap.com_m)
                + self.kd * (self.velocity_mps - snap.com_velocity_mps))


class JointTask(Task):
    """Joint-space posture of a subset of joints (e.g. the upper body)."""

    constant_jacobian = True

    def __init__(self, v_indices: list[int] | NDArray[np.int64], nv: int, kp: Gain = 0.0, kd: Gain = 0.0,
                 weight: Gain = 1.0):
        idx = np.asarray(v_indices, dtype=np.int64)
        super().__init__(idx.size, kp, kd, weight)
        self.v_indices = idx
        self.q_indices = idx + 1  # free flyer: nq = nv + 1, joints are 1-DoF
        self._jacobian = np.zeros((idx.size, nv))
        self._jacobian[np.arange(idx.size), idx] = 1.0
        self.position_rad = np.zeros(idx.size)
        self.velocity_radps = np.zeros(idx.size)
        self.acceleration_radps2 = np.zeros(idx.size)
        self._zero = np.zeros(idx.size)
        self._zero.flags.writeable = False
        # Consecutive joints are read as a slice (a view), others by index.
        consecutive = idx.size > 0 and bool(np.all(np.diff(idx) == 1))
        self._v_sel = slice(int(idx[0]), int(idx[-1]) + 1) if consecutive else idx
        self._q_sel = slice(int(idx[0]) + 1, int(idx[-1]) + 2) if consecutive else idx + 1

    def set_target(self, position_rad: FloatArray, velocity_radps: FloatArray | None = None,
                   acceleration_radps2: FloatArray | None = None) -> None:
        self.position_rad = np.asarray(position_rad, dtype=float)
        # A missing rate is the task's own zero vector (never written: targets may be the caller's arrays).
        self.velocity_radps = self._zero if velocity_radps is None else np.asarray(velocity_radps, float)
        self.acceleration_radps2 = self._zero if acceleration_radps2 is None else np.asarray(acceleration_radps2, float)

    def compute_jacobian(self, snap: DynamicsSnapshot) -> FloatArray:
        return self._jacobian

    def compute_drift(self, snap: DynamicsSnapshot) -> FloatArray:
        return np.zeros(self.dim)

    def compute_desired_acceleration(self, snap: DynamicsSnapshot) -> FloatArray:
        return (self.acceleration_radps2 + self.kp * (self.position_rad - snap.q[self._q_sel])
                + self.kd * (self.velocity_radps - snap.v[self._v_sel]))

    def write_rows(self, snap: DynamicsSnapshot, jac_out: FloatArray | None, rhs_out: FloatArray) -> None:
        if jac_out is not None:
            jac_out[:] = self._jacobian
        rhs_out[:] = self.compute_desired_acceleration(snap)  # J̇ q̇ = 0


class AngularMomentumTask(Task):
    """Centroidal angular momentum rate k̇* = kd (k* − k): damps whole-body spin (k* = 0)."""

    def __init__(self, kd: Gain = 0.0, weight: Gain = 1.0):
        super().__init__(3, 0.0, kd, weight)
        self.momentum_nms = np.zeros(3)

    def set_target(self, momentum_nms: FloatArray | None = None) -> None:
        self.momentum_nms = np.zeros(3) if momentum_nms is None else np.asarray(momentum_nms, dtype=float)

    def compute_jacobian(self, snap: DynamicsSnapshot) -> FloatArray:
        return snap.centroidal_map[3:]

    def compute_drift(self, snap: DynamicsSnapshot) -> FloatArray:
        return snap.centroidal_drift[3:]

    def compute_desired_acceleration(self, snap: DynamicsSnapshot) -> FloatArray:
        return self.kd * (self.momentum_nms - snap.momentum[3:])

    def write_rows(self, snap: DynamicsSnapshot, jac_out: FloatArray | None, rhs_out: FloatArray) -> None:
        if jac_out is not None:
            jac_out[:] = snap.centroidal_map[3:]
        np.subtract(self.kd * (self.momentum_nms - snap.momentum[3:]), snap.centroidal_drift[3:], out=rhs_out)
