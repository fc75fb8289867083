"""retarget(): KeypointMotion → RobotMotion for a quadruped, by UVM or SMR (TMR plugs in as a third method).

    source ──UVM (Eq. 1)──▶ target keypoints ──IK──▶ ᴵᴷq   (method "uvm" stops here: base transferred directly)
                                                    └──SMR (Algorithm 1, Eq. 14)──▶ q̄  (method "smr")

``contacts``: the stance schedule SMR locks the feet to — ``"cleaned"`` (default, every clip): the source's
labels plus the frames its foot keypoints are measured planted (``contacts.clean_schedule``: height + speed
with hysteresis, a minimum segment length); ``"detected"``: the measured stance alone; ``"source"``: the
schedule the source file carries, as it is. The STMR mocap labels leave trot0 on one foot 70 % of the time,
while its feet stand in diagonal pairs (README, issue 10).

``baseless`` (§VIII-E) removes the source's base trajectory first (keypoints expressed relative to the base
position, placed at the first frame's base position); SMR rebuilds the base from the anchored feet.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field, replace
from threading import Event
from typing import Callable

import numpy as np

from engine.retarget.contacts import CONTACT_SCHEDULES, StanceDetection, clean_schedule, contact_iou, detect_stance
from engine.retarget.motion import KEYPOINT_NAMES, LEGS, KeypointMotion, RobotMotion
from engine.retarget.heightmap import HeightMap
from engine.retarget.quadruped.kinematics import NotAQuadruped, QuadrupedKinematics, quadruped_kinematics
from engine.retarget.quadruped.smr import SmrOptions, smr
from engine.retarget.quadruped.uvm import RetargetCancelled, ik_trajectory, uvm_keypoints

METHODS = ("uvm", "smr")
QUADRUPEDS = ("go1", "go2", "a1", "b1", "anymal_c")


@dataclass(frozen=True)
class RetargetOptions:
    baseless: bool = False
    contacts: str = "cleaned"  # one of CONTACT_SCHEDULES
    heightmap: HeightMap = field(default_factory=HeightMap)
    smr: SmrOptions = field(default_factory=SmrOptions)


@dataclass
class RetargetOutput:
    motion: RobotMotion
    target_keypoints: np.ndarray  # (T, 16, 3) the UVM keypoints the methods aim at
    wall_time_s: float
    cpu_time_s: float = float("nan")  # this process's CPU time (the machine may be shared)


def with_contact_schedule(source: KeypointMotion, contacts: str,
                          params: StanceDetection = StanceDetection()) -> KeypointMotion:
    """``source`` with the schedule ``contacts`` names (see the module doc) from its foot keypoints
    (keypoint ``4·leg + 3``); ``source["contact_labels_iou"]`` records how far it moved from the labels."""
    if contacts == "source":
        return source
    feet = source.keypoints[:, 3::4]
    contact = (clean_schedule(source.contact, feet, source.fps, params) if contacts == "cleaned"
               else detect_stance(feet, source.fps, params))
    origin = {"cleaned": "labels + stance measured from the foot keypoints", "detected": "measured from the foot keypoints"}
    out = copy.copy(source)  # not replace(): re-validating would renormalise the quaternions (SMR bit-identical when
    out.contact = contact  # the schedule did not move, as on HopTurn)
    out.source = {**source.source, "contact_schedule": origin[contacts],
                  "contact_labels_iou": round(contact_iou(source.contact, contact), 4)}
    return out


def remove_base(source: KeypointMotion) -> KeypointMotion:
    """§VIII-E: the base position trajectory cleared; keypoints keep their motion relative to the base."""
    from engine.retarget.quadruped.uvm import source_base

    pos, _ = source_base(source)
    shift = pos - pos[0]
    kp = source.keypoints - shift[:, None, :]
    base_pos = np.repeat(pos[:1], len(pos), axis=0)
    return replace(source, keypoints=kp, base_pos=base_pos, source={**source.source, "baseless": True})


def retarget(source: KeypointMotion, robot: str, method: str = "smr", options: RetargetOptions | None = None,
             progress: Callable[[float], None] | None = None, cancel: Event | None = None) -> RobotMotion:
    """The engine API: retarget ``source`` onto quadruped ``robot`` with ``method`` ("uvm" | "smr")."""
    return retarget_detailed(source, robot, method, options, progress, cancel).motion


def retarget_detailed(source: KeypointMotion, robot: str, method: str = "smr", options: RetargetOptions | None = None,
                      progress: Callable[[float], None] | None = None, cancel: Event | None = None) -> RetargetOutput:
    options = options or RetargetOptions()
    if method not in METHODS:
        raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
    if options.contacts not in CONTACT_SCHEDULES:
        raise ValueError(f"contacts: expected one of {', '.join(CONTACT_SCHEDULES)}, got {options.contacts!r}")
    kin = quadruped_kinematics(robot)  # NotAQuadruped for bipeds
    t0, c0 = time.perf_counter(), time.process_time()
    src = with_contact_schedule(source, options.contacts)  # before the base goes: the feet are measured in the world
    src = remove_base(src) if options.baseless else src
    report = (lambda lo, hi: (lambda f: progress(lo + (hi - lo) * f))) if progress else (lambda lo, hi: None)
    target, weights, base_pos, base_rot = uvm_keypoints(src, kin)
    ik_q = ik_trajectory(kin, target, weights, base_pos, base_rot, report(0.0, 0.5 if method == "smr" else 1.0), cancel)
    if method == "uvm":
        q = ik_q
        contact_enforced = None
        smr_stats = {}
    else:
        res = smr(kin, ik_q, src.contact, src.fps, options.heightmap, options.smr, report(0.5, 1.0), cancel)
        q = res.q
        contact_enforced = res.contact
        smr_stats = {"qp_solves": res.qp_solves, "qp_failures": res.qp_failures,
                     "joint_limit_relaxed": res.joint_limit_relaxed, "flight_frames": int(res.flight.sum())}
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    motion = robot_motion_from_q(kin, q, src, method, options, contact_enforced)
    motion.source["wall_time_s"] = wall
    motion.source.update(smr_stats)
    output = RetargetOutput(motion, target, wall, cpu)
    from engine.retarget.report import summary

    motion.metrics = summary(src, output, options.heightmap)  # foot slide, IoU, penetration, … (see report.py)
    if progress:
        progress(1.0)
    return output


def robot_motion_from_q(kin: QuadrupedKinematics, q: np.ndarray, source: KeypointMotion, method: str,
                        options: RetargetOptions, contact_enforced: np.ndarray | None) -> RobotMotion:
    from engine.retarget.metrics import detect_contacts

    robot = kin.robot
    data = kin.model.createData()
    kp = np.array([kin.keypoints(data, qi) for qi in q])
    qpos = np.array([robot.mj_qpos_from_pin(qi) for qi in q])
    # qpos joint columns follow the MuJoCo model; name them in that order
    order = np.argsort(robot.mj_qpos_index)
    joint_names = [robot.joint_names[i] for i in order]
    qpos = np.concatenate([qpos[:, :7], qpos[:, np.sort(robot.mj_qpos_index)]], axis=1)
    contact = detect_contacts(kp[:, 3::4], kin.foot_radius_m, source.fps, options.heightmap)
    return RobotMotion(
        fps=source.fps, qpos=qpos, joint_names=joint_names, contact=contact, robot=robot.name, method=method,
        foot_names=list(LEGS), keypoints=kp, keypoint_names=list(KEYPOINT_NAMES),
        source={"from": source.source.get("file", ""), "source_format": source.source.get("format", ""),
                "baseless": options.baseless, "terrain": options.heightmap.to_json(), "contacts": options.contacts,
                **({"contact_labels_iou": source.source["contact_labels_iou"]} if "contact_labels_iou" in source.source else {}),
                **({"contact_enforced": contact_enforced.astype(int).tolist()} if contact_enforced is not None else {})},
    )


__all__ = ["retarget", "retarget_detailed", "RetargetOptions", "RetargetOutput", "RetargetCancelled", "NotAQuadruped",
           "METHODS", "QUADRUPEDS", "CONTACT_SCHEDULES", "remove_base", "with_contact_schedule"]
