"""The whole-body tick's :class:`~engine.control.wbc.tasks.DynamicsSnapshot` of the two feet, with pinocchio's
results read in place.

:meth:`DynamicsSnapshot.compute` asks pinocchio for each foot's placement, Jacobian and classical acceleration
(three calls a foot) and converts every result into a new numpy array (SE3 → rotation and translation, Motion →
vector, a 6 × nv Jacobian), then copies the momentum, the CoM and the base rotation out of ``data``: at 500 Hz
these conversions cost more than pinocchio's four passes. :class:`SnapshotReader` runs the same four passes and
computes the feet's quantities in one compiled call (:func:`engine.control.wbc.kernels.foot_frames`) from the
joint-level results, which it reads through numpy views of ``data``'s own memory taken once (``data.J``, the
parent joints' ``data.oMi``, ``data.v``, ``data.a``; ``data.hg``, ``data.dhg``, ``data.com[0]``): the same
numbers bit for bit (``tests/control/test_wbc_snapshot.py``).

The snapshot's arrays are the reader's buffers and views into ``data``: valid until the next :meth:`compute`
(the controller uses them within its tick; the QP keeps only arrays of its own). ``data.oMf`` is not updated
(no pinocchio frame function runs): read the feet from the snapshot.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from engine.control.wbc import kernels as _kernels
from engine.control.wbc.tasks import DynamicsSnapshot

FloatArray = NDArray[np.float64]


class SnapshotReader:
    """:meth:`DynamicsSnapshot.compute` for two frames (the feet) of one ``(model, data)`` pair."""

    def __init__(self, model: pin.Model, data: pin.Data, frame_ids: list[int]):
        if len(frame_ids) != 2:
            raise ValueError(f"SnapshotReader reads two frames (the feet), got {len(frame_ids)}")
        self.model, self.data, self.frame_ids = model, data, list(frame_ids)
        nv = model.nv
        parents = [model.frames[f].parentJoint for f in frame_ids]
        # pinocchio's frame Jacobian copies the joint Jacobians' columns of the frame's kinematic chain
        # (with mimic joints it adds columns: not handled here, DynamicsSnapshot.compute is used instead)
        self.exact = getattr(model, "nvExtended", nv) == nv
        self._support = np.zeros((2, nv), dtype=np.bool_)
        for s, parent in enumerate(parents):
            for joint in model.supports[parent]:
                if joint > 0:
                    start = model.joints[joint].idx_v
                    self._support[s, start:start + model.joints[joint].nv] = True
        self._frame_rot = np.array([model.frames[f].placement.rotation for f in frame_ids], dtype=float)
        self._frame_pos = np.array([model.frames[f].placement.translation for f in frame_ids], dtype=float)
        # views of data's memory, updated in place by every pass (data lives as long as this reader)
        self._joint_jac = data.J
        self._parent_views = tuple(view for p in parents for view in (
            data.oMi[p].rotation, data.oMi[p].translation, data.v[p].vector, data.a[p].vector))
        self._momentum, self._momentum_rate, self._com = data.hg.vector, data.dhg.vector, data.com[0]
        self._base_rot_view = data.oMi[1].rotation
        self._zeros = np.zeros(nv)
        self._zeros.flags.writeable = False
        self._mass_kg: float | None = None
        self._pos, self._rot = np.empty((2, 3)), np.empty((2, 3, 3))
        self._jac, self._drift, self._vel = np.empty((2, 6, nv)), np.empty((2, 6)), np.empty((2, 6))
        self._base_rot = np.empty((3, 3))

    def compute(self, q: FloatArray, v: FloatArray) -> DynamicsSnapshot:
        """The four passes of :meth:`DynamicsSnapshot.compute`, then the feet in one compiled call."""
        model, data = self.model, self.data
        if not self.exact:
            return DynamicsSnapshot.compute(model, data, q, v, self.frame_ids)
        # (the bindings return owned copies of data.M, data.nle and data.Ag)
        mass_matrix = pin.crba(model, data, q)
        nonlinear_effects = pin.nonLinearEffects(model, data, q, v)
        centroidal_map = pin.ccrba(model, data, q, v)
        pin.computeCentroidalMomentumTimeVariation(model, data, q, v, self._zeros)  # data.dhg, data.v, data.a
        if self._mass_kg is None:  # the model's total mass (ccrba sums the same inertias every time)
            self._mass_kg = float(data.mass[0])
        pos, rot, jac, drift, base_rot = self._pos, self._rot, self._jac, self._drift, self._base_rot
        views = self._parent_views  # left then right: rotation, translation, velocity, acceleration
        _kernels.foot_frames(self._joint_jac, views[0], views[1], views[2], views[3], views[4], views[5], views[6],
                             views[7], self._frame_rot, self._frame_pos, self._support, pos, rot, jac, drift,
                             self._base_rot_view, base_rot)
        np.matmul(jac, v, out=self._vel)
        return DynamicsSnapshot(  # (positional: the field order, q … frame_drift; keywords cost more per tick)
            q, v, mass_matrix, nonlinear_effects, centroidal_map, self._momentum_rate, self._momentum, self._com,
            self._mass_kg, base_rot, pos, rot, jac, self._vel, drift)
