"""RobotModel: the pinocchio model, the MuJoCo model and browser meshes of one robot.

Built from the normalised URDF of :mod:`engine.robot.urdf`, so both models agree on masses
and kinematics by construction (tests check 0.1 % and 1e-6 m). The compiled MJCF, the
normalised URDF and the browser meshes are cached on disk keyed by a content hash of
everything they derive from, so a second start takes well under a second.
"""

from __future__ import annotations

import hashlib
import json
import threading
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from engine.atomic_io import atomic_write_bytes
from engine.robot import meshes
from engine.robot.config import RobotConfig, RobotConfigError, load_robot_config
from engine.robot.urdf import (
    SOLE_CORNER_RADIUS_M,
    PreparedUrdf,
    mesh_sources,
    package_share,
    parse_srdf,
    prepare,
    source_path,
)

MODEL_CACHE_VERSION = "5"
TIMESTEP_S = 0.002
FLOOR_FRICTION = 1.0
IMPRATIO = 5.0

# Collision bits: floor collides with everything; robot geoms collide with the floor and,
# when the config enables it, with each other (minus excluded body pairs).
FLOOR_BIT, ROBOT_BIT = 1, 2


@dataclass
class BodyMesh:
    """A browser-weight mesh of one MuJoCo body, in the body frame."""

    body: str
    vertices: np.ndarray  # (V, 3) float32
    faces: np.ndarray  # (F, 3) int32
    rgba: tuple[float, float, float, float]


@dataclass
class RobotModel:
    config: RobotConfig
    urdf_text: str
    mj_model: mujoco.MjModel
    pin_model: pin.Model
    joint_names: list[str]  # actuated joints, pinocchio order
    mj_qpos_index: np.ndarray  # mujoco qpos address of each joint in joint_names
    mj_dof_index: np.ndarray  # mujoco dof address of each joint
    mj_actuator_index: np.ndarray  # mujoco actuator id of each joint
    effort_limits: np.ndarray  # (n,) N·m
    kp: np.ndarray
    kd: np.ndarray
    q_standing: np.ndarray  # pinocchio configuration (nq,) with the feet on the ground
    body_meshes: list[BodyMesh] = field(default_factory=list)
    cache_dir: Path | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    # ---------------------------------------------------------------- basic facts
    @property
    def name(self) -> str:
        return self.config.name

    @property
    def kind(self) -> str:
        return self.config.kind

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @cached_property
    def mass_kg(self) -> float:
        return float(sum(inertia.mass for inertia in self.pin_model.inertias))

    @cached_property
    def body_names(self) -> list[str]:
        """MuJoCo body names, world excluded (index i ↔ mujoco body id i+1)."""
        return [self.mj_model.body(i).name for i in range(1, self.mj_model.nbody)]

    @cached_property
    def joint_lower(self) -> np.ndarray:
        return np.array([self.pin_model.lowerPositionLimit[7 + i] for i in range(self.n_joints)])

    @cached_property
    def joint_upper(self) -> np.ndarray:
        return np.array([self.pin_model.upperPositionLimit[7 + i] for i in range(self.n_joints)])

    @cached_property
    def height_m(self) -> float:
        """Standing-up height: top of the visual meshes above the lowest contact, all joints zero."""
        q = self.q_standing.copy()
        q[7:] = 0.0
        qpos = self.mj_qpos_from_pin(q)
        data = mujoco.MjData(self.mj_model)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(self.mj_model, data)
        zs = [np.full(1, np.inf)]
        top = -np.inf
        for bm in self.body_meshes:
            bid = self.mj_model.body(bm.body).id
            world = bm.vertices @ data.xmat[bid].reshape(3, 3).T + data.xpos[bid]
            top = max(top, float(world[:, 2].max()))
            zs.append(world[:, 2])
        low = self.lowest_contact_z(data) if self.kind != "source-skeleton" else float(np.concatenate(zs).min())
        return top - low

    # ---------------------------------------------------------------- conversions
    def mj_qpos_from_pin(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio q (xyz, quat xyzw, joints) → MuJoCo qpos (xyz, quat wxyz, joints)."""
        qpos = np.zeros(self.mj_model.nq)
        qpos[0:3] = q[0:3]
        qpos[3] = q[6]
        qpos[4:7] = q[3:6]
        qpos[self.mj_qpos_index] = q[7:]
        return qpos

    def pin_q_from_mj(self, qpos: np.ndarray) -> np.ndarray:
        """MuJoCo qpos (xyz, quat wxyz, joints) → pinocchio q (xyz, quat xyzw, joints): one gather."""
        return qpos[self._pin_q_gather]

    def pin_v_from_mj(self, qvel: np.ndarray, qpos: np.ndarray) -> np.ndarray:
        """MuJoCo qvel (free joint: world linear, body angular) → pinocchio v (base-frame linear and angular)."""
        v = qvel[self._pin_v_gather]  # angular and joint rates as they are
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, qpos[3:7])
        # Rᵀ v on floats: what ``rot.reshape(3, 3).T @ qvel[0:3]`` computes (a sequential dot per row of
        # Rᵀ; tests/control/test_stack_speed_references.py asserts it bit for bit), without matmul's dispatch.
        r0, r1, r2, r3, r4, r5, r6, r7, r8 = rot.tolist()
        vx, vy, vz = v[0:3].tolist()
        v[0:3] = (r0 * vx + r3 * vy + r6 * vz, r1 * vx + r4 * vy + r7 * vz, r2 * vx + r5 * vy + r8 * vz)
        return v

    @cached_property
    def _pin_q_gather(self) -> np.ndarray:
        """qpos addresses of pinocchio's q entries: xyz, the quaternion's x y z then w, the joints."""
        return np.concatenate([[0, 1, 2, 4, 5, 6, 3], self.mj_qpos_index]).astype(np.intp)

    @cached_property
    def _pin_v_gather(self) -> np.ndarray:
        """qvel addresses of pinocchio's v entries (the linear part is rotated afterwards)."""
        return np.concatenate([np.arange(6), self.mj_dof_index]).astype(np.intp)

    def mj_standing_qpos(self) -> np.ndarray:
        return self.mj_qpos_from_pin(self.q_standing)

    def lowest_contact_z(self, data: mujoco.MjData) -> float:
        """Lowest point of the contact geometry (sole-corner or foot spheres) in world z."""
        lows = []
        for gid in self.contact_geom_ids:
            lows.append(data.geom_xpos[gid][2] - self.mj_model.geom_size[gid][0])
        return float(min(lows)) if lows else 0.0

    @cached_property
    def contact_geom_ids(self) -> list[int]:
        """MuJoCo ids of the contact-model spheres (feet)."""
        links = {s.link for s in self.config.soles.values()} | {f.link for f in self.config.feet}
        ids = []
        for gid in range(self.mj_model.ngeom):
            geom = self.mj_model.geom(gid)
            body = self.mj_model.body(int(self.mj_model.geom_bodyid[gid])).name
            if body in links and geom.type[0] == mujoco.mjtGeom.mjGEOM_SPHERE and self.mj_model.geom_contype[gid]:
                ids.append(gid)
        return ids

    def frame_id(self, name: str) -> int:
        fid = self.pin_model.getFrameId(name)
        if fid >= len(self.pin_model.frames):
            raise KeyError(name)
        return fid


# ----------------------------------------------------------------------------- building


def _cache_key(cfg: RobotConfig) -> str:
    h = hashlib.sha256()
    h.update(MODEL_CACHE_VERSION.encode())
    h.update(meshes.CACHE_VERSION.encode())
    h.update(mujoco.__version__.encode())
    h.update(cfg.path.read_bytes())
    h.update(Path(__file__).read_bytes())
    h.update((Path(__file__).parent / "urdf.py").read_bytes())
    h.update(source_path(cfg, cfg.urdf).read_bytes())
    if cfg.source_package == "local":  # project-made meshes may change with the URDF untouched
        for mesh in mesh_sources(cfg):
            if mesh.is_file():
                h.update(mesh.read_bytes())
    if cfg.srdf:
        h.update(source_path(cfg, cfg.srdf).read_bytes())
    return h.hexdigest()[:16]


def _standing_joint_values(cfg: RobotConfig, srdf_states: dict[str, dict[str, float]] | None) -> dict[str, float]:
    values: dict[str, float] = {}
    if cfg.standing_srdf_state:
        if not srdf_states or cfg.standing_srdf_state not in srdf_states:
            raise RobotConfigError(
                f"{cfg.path.name}: standing.srdf_state: {cfg.standing_srdf_state!r} not in {cfg.srdf}"
            )
        values.update(srdf_states[cfg.standing_srdf_state])
    values.update(cfg.standing_pose)
    return values


def _build_mujoco(cfg: RobotConfig, prepared: PreparedUrdf) -> mujoco.MjSpec:
    spec = mujoco.MjSpec.from_string(prepared.mujoco_text)
    spec.modelname = cfg.name
    spec.option.timestep = TIMESTEP_S
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    # Elliptic friction cones with a raised impedance ratio: MuJoCo's soft friction otherwise lets
    # loaded soles creep by millimetres per step (rubber soles on a floor do not).
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = IMPRATIO
    spec.visual.global_.offwidth = 640
    spec.visual.global_.offheight = 480

    root = spec.body(cfg.root_link)
    if root is None:
        raise RobotConfigError(f"{cfg.path.name}: model.root_link: {cfg.root_link!r} is not a body")
    root.add_freejoint(name="root")  # source skeletons too: a free base keeps poses uniform

    world = spec.worldbody
    world.add_light(name="sun", pos=[0, 0, 4], dir=[0, 0, -1], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    floor = world.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05])
    floor.contype = FLOOR_BIT
    floor.conaffinity = FLOOR_BIT | ROBOT_BIT
    floor.friction = [FLOOR_FRICTION, 0.005, 0.0001]

    for geom in spec.geoms:
        if geom.name == "floor":
            continue
        if geom.contype == 0 and geom.conaffinity == 0:
            geom.group = 2  # visual
            continue
        geom.group = 3
        geom.contype = ROBOT_BIT
        geom.conaffinity = FLOOR_BIT | (ROBOT_BIT if cfg.self_collision else 0)
        geom.condim = 3
        geom.friction = [FLOOR_FRICTION, 0.005, 0.0001]

    if prepared.srdf and cfg.srdf_collision_excludes:
        bodies = {b.name for b in spec.bodies}
        for a, b in prepared.srdf.disabled_pairs:
            if a in bodies and b in bodies and a != b:
                spec.add_exclude(bodyname1=a, bodyname2=b)

    # Joints: armature from the config; one torque actuator per actuated joint.
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_FREE:
            continue
        rule = cfg.gain_rule(joint.name)
        if rule is not None:
            joint.armature = rule.armature
        if cfg.simulated:
            effort = prepared.effort_limits.get(joint.name, 0.0) or 1000.0
            act = spec.add_actuator(name=joint.name, target=joint.name)
            act.trntype = mujoco.mjtTrn.mjTRN_JOINT
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = [-effort, effort]

    # IMU on the root link for the state estimator.
    imu = root.add_site(name="imu", pos=[0, 0, 0])
    spec.add_sensor(name="imu_quat", type=mujoco.mjtSensor.mjSENS_FRAMEQUAT, objtype=mujoco.mjtObj.mjOBJ_SITE, objname="imu")
    spec.add_sensor(name="imu_gyro", type=mujoco.mjtSensor.mjSENS_GYRO, objtype=mujoco.mjtObj.mjOBJ_SITE, objname="imu")
    spec.add_sensor(name="imu_accel", type=mujoco.mjtSensor.mjSENS_ACCELEROMETER, objtype=mujoco.mjtObj.mjOBJ_SITE, objname="imu")
    del imu
    for side, sole in cfg.soles.items():
        spec.body(sole.link).add_site(name=f"{side}_foot", pos=list(sole.center))
    return spec


def _auto_excludes(spec: mujoco.MjSpec, model: mujoco.MjModel, qpos_list: list[np.ndarray]) -> list[tuple[str, str]]:
    """Robot body pairs already touching in reference poses (meshes overlapping at rest)."""
    data = mujoco.MjData(model)
    pairs: set[tuple[str, str]] = set()
    for qpos in qpos_list:
        data.qpos[:] = qpos
        data.qpos[2] += 5.0  # lift clear of the floor
        mujoco.mj_forward(model, data)
        for c in data.contact[: data.ncon]:
            b1, b2 = int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])
            if b1 != b2 and b1 > 0 and b2 > 0:
                pairs.add(tuple(sorted((model.body(b1).name, model.body(b2).name))))
    return sorted(pairs)


def _extract_body_meshes(model: mujoco.MjModel) -> list[BodyMesh]:
    out: list[BodyMesh] = []
    per_body: dict[int, list[tuple[np.ndarray, np.ndarray, np.ndarray, float]]] = {}
    for gid in range(model.ngeom):
        if model.geom_group[gid] != 2 or model.geom_type[gid] != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        mid = int(model.geom_dataid[gid])
        v0, nv = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
        f0, nf = int(model.mesh_faceadr[mid]), int(model.mesh_facenum[mid])
        verts = model.mesh_vert[v0:v0 + nv].astype(np.float64)
        faces = model.mesh_face[f0:f0 + nf].astype(np.int64)
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[gid])
        verts = verts @ rot.reshape(3, 3).T + model.geom_pos[gid]
        area = float(nf)
        per_body.setdefault(int(model.geom_bodyid[gid]), []).append((verts, faces, model.geom_rgba[gid].copy(), area))
    for bid, parts in sorted(per_body.items()):
        verts_all, faces_all, offset = [], [], 0
        for verts, faces, _, _ in parts:
            verts_all.append(verts)
            faces_all.append(faces + offset)
            offset += len(verts)
        rgba = max(parts, key=lambda p: p[3])[2]
        out.append(BodyMesh(model.body(bid).name, np.concatenate(verts_all).astype(np.float32),
                            np.concatenate(faces_all).astype(np.int32),
                            (float(rgba[0]), float(rgba[1]), float(rgba[2]), float(rgba[3]))))
    return out


def _save_body_meshes(path: Path, body_meshes: list[BodyMesh]) -> None:
    arrays: dict[str, np.ndarray] = {}
    index = []
    for i, bm in enumerate(body_meshes):
        arrays[f"v{i}"] = bm.vertices
        arrays[f"f{i}"] = bm.faces
        index.append({"body": bm.body, "rgba": list(bm.rgba)})
    arrays["index"] = np.frombuffer(json.dumps(index).encode(), dtype=np.uint8)
    import io

    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)  # type: ignore[arg-type]  # numpy's stub types **kwds as the allow_pickle flag
    atomic_write_bytes(path, buf.getvalue())


def _load_body_meshes(path: Path) -> list[BodyMesh]:
    with np.load(path, allow_pickle=False) as z:
        index = json.loads(bytes(z["index"]).decode())
        return [BodyMesh(e["body"], z[f"v{i}"], z[f"f{i}"], tuple(e["rgba"])) for i, e in enumerate(index)]


def _ground_standing_pose(cfg: RobotConfig, mj_model: mujoco.MjModel, q: np.ndarray, to_qpos, contact_ids) -> np.ndarray:
    """Set the base height so the lowest contact point touches the floor."""
    data = mujoco.MjData(mj_model)
    q = q.copy()
    q[2] = 0.0
    data.qpos[:] = to_qpos(q)
    mujoco.mj_kinematics(mj_model, data)
    if contact_ids:
        low = min(data.geom_xpos[g][2] - mj_model.geom_size[g][0] for g in contact_ids)
    else:
        low = min(float(data.xpos[i][2]) for i in range(1, mj_model.nbody))
    q[2] = -low
    return q


_MODEL_CACHE: dict[str, RobotModel] = {}
_MODEL_CACHE_LOCK = threading.Lock()


def load_robot(name: str, use_cache: bool = True) -> RobotModel:
    """Build (or load from the on-disk cache) robot ``name``. Memoised per process."""
    with _MODEL_CACHE_LOCK:
        if use_cache and name in _MODEL_CACHE:
            return _MODEL_CACHE[name]
    cfg = load_robot_config(name)
    model = build_robot(cfg, use_cache=use_cache)
    with _MODEL_CACHE_LOCK:
        _MODEL_CACHE[name] = model
    return model


def build_robot(cfg: RobotConfig, use_cache: bool = True) -> RobotModel:
    cache_dir = meshes.cache_root() / "robots" / f"{cfg.name}-{_cache_key(cfg)}"
    shared_mesh_dir = meshes.cache_root()
    mjcf_path, urdf_path, mesh_path = cache_dir / "model.xml", cache_dir / "robot.urdf", cache_dir / "visual.npz"
    meta_path = cache_dir / "meta.json"

    if use_cache and mjcf_path.is_file() and urdf_path.is_file() and mesh_path.is_file() and meta_path.is_file():
        urdf_text = urdf_path.read_text()
        mj_model = mujoco.MjModel.from_xml_path(str(mjcf_path))
        body_meshes = _load_body_meshes(mesh_path)
        meta = json.loads(meta_path.read_text())
        efforts = meta["effort_limits"]
    else:
        prepared = prepare(cfg, shared_mesh_dir)
        urdf_text = prepared.text
        spec = _build_mujoco(cfg, prepared)
        mj_model = spec.compile()
        body_meshes = _extract_body_meshes(mj_model)
        efforts = prepared.effort_limits
        meta = {"effort_limits": efforts, "auto_excludes": []}
        if cfg.self_collision:
            # Bodies whose collision hulls already overlap at rest can never separate: exclude them.
            tmp = _finish(cfg, urdf_text, mj_model, efforts, body_meshes, None, prepared.srdf)
            zero = tmp.q_standing.copy()
            zero[7:] = 0.0
            pairs = _auto_excludes(spec, mj_model, [tmp.mj_qpos_from_pin(tmp.q_standing), tmp.mj_qpos_from_pin(zero)])
            for a, b in pairs:
                spec.add_exclude(bodyname1=a, bodyname2=b)
            meta["auto_excludes"] = pairs
            mj_model = spec.compile()
        if use_cache:
            cache_dir.mkdir(parents=True, exist_ok=True)
            atomic_write_bytes(mjcf_path, spec.to_xml().encode())
            atomic_write_bytes(urdf_path, urdf_text.encode())
            _save_body_meshes(mesh_path, body_meshes)
            atomic_write_bytes(meta_path, json.dumps(meta, indent=1).encode())
            mj_model = mujoco.MjModel.from_xml_path(str(mjcf_path))  # what later loads will see
    srdf = parse_srdf(source_path(cfg, cfg.srdf).read_text()) if cfg.srdf else None
    model = _finish(cfg, urdf_text, mj_model, efforts, body_meshes, cache_dir if use_cache else None, srdf)
    return model


def _finish(cfg, urdf_text, mj_model, efforts, body_meshes, cache_dir, srdf) -> RobotModel:
    pin_model = pin.buildModelFromXML(urdf_text, pin.JointModelFreeFlyer())
    joint_names = [pin_model.names[i] for i in range(2, pin_model.njoints)]
    for jid in range(2, pin_model.njoints):
        if pin_model.joints[jid].nq != 1:
            raise RobotConfigError(f"{cfg.path.name}: joint {pin_model.names[jid]!r} is not a 1-DoF joint")
    qpos_idx, dof_idx, act_idx = [], [], []
    for jn in joint_names:
        jid = mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_JOINT, jn)
        if jid < 0:
            raise RobotConfigError(f"{cfg.path.name}: joint {jn!r} missing from the MuJoCo model")
        qpos_idx.append(int(mj_model.jnt_qposadr[jid]))
        dof_idx.append(int(mj_model.jnt_dofadr[jid]))
        act_idx.append(mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_ACTUATOR, jn))

    # Armature in pinocchio too, so inverse dynamics sees the same rotor inertia as MuJoCo.
    armature = np.zeros(pin_model.nv)
    kp = np.zeros(len(joint_names))
    kd = np.zeros(len(joint_names))
    for i, jn in enumerate(joint_names):
        rule = cfg.gain_rule(jn)
        if rule is None and cfg.simulated:
            raise RobotConfigError(f"{cfg.path.name}: gains: no pattern matches joint {jn!r}")
        if rule is not None:
            armature[6 + i] = rule.armature
            kp[i], kd[i] = rule.kp, rule.kd
    pin_model.armature = armature

    for jn in [*cfg.upper_body_joints, *cfg.standing_pose]:
        if jn not in joint_names:
            import difflib

            hint = difflib.get_close_matches(jn, joint_names, n=1)
            extra = f" (did you mean {hint[0]!r}?)" if hint else ""
            raise RobotConfigError(f"{cfg.path.name}: joint {jn!r} does not exist on {cfg.urdf}{extra}")

    values = _standing_joint_values(cfg, srdf.states if srdf else None)
    q = pin.neutral(pin_model)
    for i, jn in enumerate(joint_names):
        if jn in values:
            q[7 + i] = np.clip(values[jn], pin_model.lowerPositionLimit[7 + i], pin_model.upperPositionLimit[7 + i])
    if cfg.up_axis == "y":
        q[3:7] = [np.sin(np.pi / 4), 0.0, 0.0, np.cos(np.pi / 4)]  # +90° about x: y-up → z-up

    _add_contact_frames(cfg, pin_model)

    model = RobotModel(
        config=cfg, urdf_text=urdf_text, mj_model=mj_model, pin_model=pin_model, joint_names=joint_names,
        mj_qpos_index=np.array(qpos_idx), mj_dof_index=np.array(dof_idx), mj_actuator_index=np.array(act_idx),
        effort_limits=np.array([efforts.get(jn, 0.0) for jn in joint_names]), kp=kp, kd=kd,
        q_standing=q, body_meshes=body_meshes, cache_dir=cache_dir,
    )
    model.q_standing = _ground_standing_pose(cfg, mj_model, q, model.mj_qpos_from_pin, model.contact_geom_ids)
    return model


def _add_contact_frames(cfg: RobotConfig, pin_model: pin.Model) -> None:
    """Frames the controllers use: ``left_foot``/``right_foot`` at the sole centres with their
    four corners ``left_foot_c0..3`` (bipeds), ``foot_<name>`` at each foot sphere's centre
    (quadrupeds), and ``trunk`` for placo's humanoid helpers."""

    def add(name: str, link: str, xyz) -> None:
        if pin_model.existFrame(name):
            return
        parent = pin_model.frames[pin_model.getFrameId(link)]
        placement = parent.placement * pin.SE3(np.eye(3), np.asarray(xyz, dtype=float))
        pin_model.addFrame(pin.Frame(name, parent.parentJoint, pin_model.getFrameId(link), placement, pin.FrameType.OP_FRAME))

    for side, sole in cfg.soles.items():
        add(f"{side}_foot", sole.link, sole.center)
        for i, corner in enumerate(sole.corners()):
            add(f"{side}_foot_c{i}", sole.link, corner)
    for foot in cfg.feet:
        add(f"foot_{foot.name}", foot.link, foot.offset)
    if cfg.trunk_link and not pin_model.existFrame("trunk"):
        add("trunk", cfg.trunk_link, (0.0, 0.0, 0.0))


def contact_frame_names(cfg: RobotConfig) -> list[str]:
    """Point contacts of the contact model: sole corners (bipeds) or foot centres (quadrupeds)."""
    names = [f"{side}_foot_c{i}" for side in cfg.soles for i in range(4)]
    return names + [f"foot_{f.name}" for f in cfg.feet]


def check_package() -> Path:
    """The example-robot-data share folder (raises RobotConfigError when missing)."""
    return package_share()


__all__ = ["RobotModel", "BodyMesh", "load_robot", "build_robot", "SOLE_CORNER_RADIUS_M"]
