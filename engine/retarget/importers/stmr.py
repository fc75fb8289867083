"""The STMR paper's own clips (terry97-guel/STMR_RL datasets): ``<clip>_keypoints.npz`` + ``<clip>_contact.json``.

The npz holds the 16 keypoints in the *base* frame (hip sites constant), legs FR, FL, RR, RL, with
``base_pos``/``base_rotmat``; its ``base_pos`` z is offset by a per-clip constant (≈ −0.28 m against the
clip's ``_raw.txt``), so world keypoints are ``base_pos + R kp`` shifted to put the stance feet on z = 0.
The contact json (keys FR, FL, RR, RL) is the source's schedule and agrees with the npz's labels (contact
feet are low and slow under these labels, checked numerically); without a json the npz's own ``contact``
is used. Legs are mapped to FL, FR, RL, RR by name here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from engine.retarget.importers import ImportFormatError, read_json, read_source_npz
from engine.retarget.motion import KEYPOINT_KINDS, LEGS, KeypointMotion, _contact, _float_array, _names

_SITE = {"hip": "hip", "thigh": "thigh", "knee": "calf", "foot": "foot"}


def import_stmr_keypoints(path: Path) -> KeypointMotion:
    name = path.name
    data = read_source_npz(path)
    for key in ("keypoints", "keypoint_names", "base_pos", "base_rotmat"):
        if key not in data:
            raise ImportFormatError(f"{name}: {key}: missing")
    kp = _float_array(name, "keypoints", data["keypoints"], (None, 16, 3))
    t = kp.shape[0]
    if t < 2:
        raise ImportFormatError(f"{name}: keypoints: expected at least 2 frames, got {t}")
    names = _names(name, "keypoint_names", data["keypoint_names"], 16)
    order = []
    for leg in LEGS:
        for kind in KEYPOINT_KINDS:
            site = f"{leg}_{_SITE[kind]}_site"
            if site not in names:
                raise ImportFormatError(f"{name}: keypoint_names: expected {site!r}")
            order.append(names.index(site))
    kp = kp[:, order]
    base_pos = _float_array(name, "base_pos", data["base_pos"], (t, 3))
    rot = _float_array(name, "base_rotmat", data["base_rotmat"], (t, 3, 3))
    off = np.abs(np.einsum("tij,tkj->tik", rot, rot) - np.eye(3)).max(axis=(1, 2))
    if np.any(off > 1e-3) or np.any(np.linalg.det(rot) < 0):
        i = int(np.argmax(off)) if np.any(off > 1e-3) else int(np.argmax(np.linalg.det(rot) < 0))
        raise ImportFormatError(f"{name}: base_rotmat: expected rotation matrices, frame {i} is not one")
    if "time" in data and np.asarray(data["time"]).size > 1:
        times = _float_array(name, "time", data["time"], (None,))
        dt = float(np.median(np.diff(times)))
        if not 0.0001 <= dt <= 10:
            raise ImportFormatError(f"{name}: time: expected increasing times (0.1 ms to 10 s apart), median step {dt:g} s")
        fps = round(1.0 / dt, 6)
    else:
        fps = 20.0
    world = base_pos[:, None, :] + np.einsum("tij,tkj->tki", rot, kp)

    contact_file = path.with_name(path.name.replace("_keypoints.npz", "_contact.json"))
    contact_source = "npz"
    if contact_file.is_file() and contact_file != path:
        raw = read_json(contact_file)
        if not isinstance(raw, dict):
            raise ImportFormatError(f"{contact_file.name}: expected an object with keys FR, FL, RR, RL")
        cols = []
        for leg in LEGS:
            col = raw.get(leg)
            if not isinstance(col, list) or len(col) != t:
                raise ImportFormatError(f"{contact_file.name}: {leg}: expected {t} booleans")
            cols.append([bool(v) for v in col])
        contact = np.array(cols).T
        contact_source = contact_file.name
    elif "contact" in data:
        order_feet = _names(name, "foot_order", data.get("foot_order", np.array(["FR", "FL", "RR", "RL"])), 4)
        if sorted(order_feet) != sorted(LEGS):
            raise ImportFormatError(f"{name}: foot_order: expected FR, FL, RR, RL in some order, got {order_feet}")
        c = _contact(name, data["contact"], t, 4)
        contact = c[:, [order_feet.index(leg) for leg in LEGS]]
    else:
        raise ImportFormatError(f"{name}: contact: missing (and no {contact_file.name})")
    feet_z = world[:, 3::4, 2]
    ground = float(np.median(feet_z[contact])) if contact.any() else float(np.percentile(feet_z, 2))
    world[:, :, 2] -= ground
    base_pos = base_pos.copy()
    base_pos[:, 2] -= ground
    quat = np.array([pin.Quaternion(r).coeffs() for r in rot])  # x,y,z,w
    quat = quat[:, [3, 0, 1, 2]]
    clip = path.name.replace("_keypoints.npz", "")
    return KeypointMotion(
        fps=fps, keypoints=world, contact=contact, base_pos=base_pos, base_quat=quat,
        source={"file": name, "format": "stmr-keypoints", "clip": clip, "contact_from": contact_source,
                "ground_shift_m": -ground, "licence": "non-commercial test data (STMR_RL / MANN / Peng et al.)"},
    )
