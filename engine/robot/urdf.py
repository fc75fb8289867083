"""URDF preparation: the single source of truth from which every model is built.

The package URDF is read as text and normalised once: gazebo/transmission tags dropped,
inertias made physically valid (the same bounds MuJoCo would otherwise apply silently, so
pinocchio and MuJoCo see identical masses), meshes converted/decimated into the cache,
foot contact geometry replaced by the contact model of the config (sole-corner spheres or
foot spheres, matching the controller's contact points), and extra frames added for the
tools that need them. Package files are never edited.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.robot import meshes
from engine.robot.config import RobotConfig, RobotConfigError

MIN_MASS_KG = 1e-3
MIN_INERTIA = 1e-6
SOLE_CORNER_RADIUS_M = 0.005

MUJOCO_COMPILER = (
    '<compiler discardvisual="false" fusestatic="false" balanceinertia="true" inertiafromgeom="false" '
    'boundmass="1e-3" boundinertia="1e-6" strippath="false" angle="radian"/>'
)


def package_share() -> Path:
    """``.../cmeel.prefix/share`` of the installed example-robot-data distribution."""
    from importlib import metadata

    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        raise RobotConfigError("example-robot-data is not installed (run `make setup`)") from None
    share = Path(str(dist.locate_file("cmeel.prefix/share")))
    if not (share / "example-robot-data" / "robots").is_dir():
        raise RobotConfigError(f"example-robot-data robots not found under {share}")
    return share


def resolve_package_path(uri: str, share: Path | None, base: Path | None = None) -> Path:
    """A URDF mesh filename as a path: ``package://`` under ``share``, ``file://`` as is, and a
    relative path under ``base`` (the URDF's folder)."""
    if uri.startswith("package://"):
        if share is None:
            raise RobotConfigError(f"{uri}: package:// paths need example-robot-data")
        return share / uri[len("package://"):]
    if uri.startswith("file://"):
        return Path(uri[len("file://"):])
    path = Path(uri)
    return path if path.is_absolute() or base is None else base / path


def source_path(cfg: RobotConfig, rel: str) -> Path:
    """A source file named by the config: in example-robot-data, or next to the config file
    (``source.package = "local"``: robots the project makes itself)."""
    if cfg.source_package == "local":
        path = cfg.path.parent / rel
        if not path.is_file():
            raise RobotConfigError(f"{cfg.path.name}: source.urdf: {rel} not found next to {cfg.path.name}")
        return path
    path = package_share() / "example-robot-data" / rel
    if not path.is_file():
        raise RobotConfigError(f"{cfg.path.name}: source: {rel} not found in example-robot-data")
    return path


def mesh_sources(cfg: RobotConfig) -> list[Path]:
    """Every mesh file the config's URDF names (sorted, unique): what the model derives from."""
    urdf_path = source_path(cfg, cfg.urdf)
    share = package_share() if cfg.source_package != "local" else None
    root = ET.fromstring(urdf_path.read_text())
    paths = {resolve_package_path(el.get("filename", ""), share, urdf_path.parent) for el in root.iter("mesh")}
    return sorted(paths)


@dataclass(frozen=True)
class Srdf:
    disabled_pairs: tuple[tuple[str, str], ...]
    states: dict[str, dict[str, float]]


def parse_srdf(text: str) -> Srdf:
    root = ET.fromstring(text)
    pairs = tuple((e.get("link1", ""), e.get("link2", "")) for e in root.iter("disable_collisions"))
    states: dict[str, dict[str, float]] = {}
    for gs in root.iter("group_state"):
        values: dict[str, float] = {}
        for j in gs.iter("joint"):
            raw = (j.get("value") or "").split()
            if len(raw) == 1:
                values[j.get("name", "")] = float(raw[0])
        states[gs.get("name", "")] = values
    return Srdf(pairs, states)


def _fix_inertial(link: ET.Element) -> None:
    """Give every link a mass ≥ 1e-3 kg and a valid inertia (eigenvalues ≥ 1e-6, triangle rule)."""
    inertial = link.find("inertial")
    if inertial is None:
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", {"xyz": "0 0 0", "rpy": "0 0 0"})
        ET.SubElement(inertial, "mass", {"value": "0"})
        ET.SubElement(inertial, "inertia", {k: "0" for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")})
    mass_el = inertial.find("mass")
    if mass_el is None:
        mass_el = ET.SubElement(inertial, "mass", {"value": "0"})
    mass = float(mass_el.get("value", "0"))
    if mass < MIN_MASS_KG:
        mass_el.set("value", repr(MIN_MASS_KG))
    inertia = inertial.find("inertia")
    if inertia is None:
        inertia = ET.SubElement(inertial, "inertia", {k: "0" for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")})
    g = {k: float(inertia.get(k, "0")) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    mat = np.array([[g["ixx"], g["ixy"], g["ixz"]], [g["ixy"], g["iyy"], g["iyz"]], [g["ixz"], g["iyz"], g["izz"]]])
    w, v = np.linalg.eigh(mat)
    w_fixed = np.maximum(w, MIN_INERTIA)
    # Triangle inequality of principal moments (what MuJoCo's balanceinertia enforces).
    for i in range(3):
        others = w_fixed.sum() - w_fixed[i]
        if w_fixed[i] > others:
            w_fixed[i] = others
    if np.allclose(w, w_fixed, rtol=0, atol=1e-12):
        return
    fixed = v @ np.diag(w_fixed) @ v.T
    for k, (i, j) in {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2), "izz": (2, 2)}.items():
        inertia.set(k, repr(float(fixed[i, j])))


def _regularize_link(link: ET.Element) -> None:
    """Fix for packaged links whose inertia is singular/invalid: floor eigenvalues at 1 % of the largest."""
    inertia = link.find("inertial/inertia")
    if inertia is None:
        return
    g = {k: float(inertia.get(k, "0")) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    mat = np.array([[g["ixx"], g["ixy"], g["ixz"]], [g["ixy"], g["iyy"], g["iyz"]], [g["ixz"], g["iyz"], g["izz"]]])
    w, v = np.linalg.eigh(mat)
    w = np.maximum(w, 0.01 * max(w.max(), MIN_INERTIA))
    fixed = v @ np.diag(w) @ v.T
    for k, (i, j) in {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2), "izz": (2, 2)}.items():
        inertia.set(k, repr(float(fixed[i, j])))


def _sphere_collision(link: ET.Element, xyz: tuple[float, float, float], radius: float) -> None:
    col = ET.SubElement(link, "collision")
    ET.SubElement(col, "origin", {"xyz": " ".join(repr(float(c)) for c in xyz), "rpy": "0 0 0"})
    geom = ET.SubElement(col, "geometry")
    ET.SubElement(geom, "sphere", {"radius": repr(float(radius))})


@dataclass(frozen=True)
class PreparedUrdf:
    text: str  # normalised URDF: pinocchio reads this
    mujoco_text: str  # the same plus the <mujoco><compiler/> block
    links: tuple[str, ...]
    effort_limits: dict[str, float]
    srdf: Srdf | None


def prepare(cfg: RobotConfig, cache_dir: Path) -> PreparedUrdf:
    """Normalise ``cfg``'s URDF (see module docstring). Converted meshes land in ``cache_dir``."""
    urdf_path = source_path(cfg, cfg.urdf)
    share = package_share() if cfg.source_package != "local" else None
    root = ET.fromstring(urdf_path.read_text())
    for tag in ("gazebo", "transmission"):
        for el in root.findall(tag):
            root.remove(el)

    links = {link.get("name", ""): link for link in root.findall("link")}
    for name in (cfg.root_link, cfg.trunk_link, *[s.link for s in cfg.soles.values()], *[f.link for f in cfg.feet]):
        if name is not None and name not in links:
            raise RobotConfigError(f"{cfg.path.name}: link {name!r} not in {cfg.urdf}")
    for name in cfg.regularize_inertia_links:
        if name not in links:
            raise RobotConfigError(f"{cfg.path.name}: fixes.regularize_inertia_links: link {name!r} not in {cfg.urdf}")
        _regularize_link(links[name])
    for link in links.values():
        _fix_inertial(link)

    # Contact model: replace the foot links' collision geometry.
    for sole in cfg.soles.values():
        link = links[sole.link]
        for col in link.findall("collision"):
            link.remove(col)
        for x, y, z in sole.corners():
            _sphere_collision(link, (x, y, z + SOLE_CORNER_RADIUS_M), SOLE_CORNER_RADIUS_M)
    for foot in cfg.feet:
        link = links[foot.link]
        for col in link.findall("collision"):
            link.remove(col)
        _sphere_collision(link, foot.offset, foot.radius_m)

    # Meshes: convert into the cache, decimating visuals to the robot's face budget.
    visual_sources: list[tuple[ET.Element, Path]] = []
    collision_sources: list[tuple[ET.Element, Path]] = []
    for link in links.values():
        for role, bucket in (("visual", visual_sources), ("collision", collision_sources)):
            for el in link.findall(f"{role}/geometry/mesh"):
                src = resolve_package_path(el.get("filename", ""), share, urdf_path.parent)
                if not src.is_file():
                    raise RobotConfigError(f"{cfg.path.name}: mesh {el.get('filename')} not found")
                bucket.append((el, src))
    counts = {src: meshes.face_count(src) for _, src in visual_sources}
    total = max(sum(counts[src] for _, src in visual_sources), 1)  # per use: a leg mesh counts 4x
    for el, src in visual_sources:
        target = max(200, int(cfg.visual_face_budget * counts[src] / total))
        el.set("filename", str(meshes.convert(src, "visual", target, cfg.dae_up_axis, cache_dir)))
    for el, src in collision_sources:
        el.set("filename", str(meshes.convert(src, "collision", cfg.collision_face_budget, cfg.dae_up_axis, cache_dir)))

    efforts: dict[str, float] = {}
    for joint in root.findall("joint"):
        if joint.get("type") in ("revolute", "continuous", "prismatic"):
            limit = joint.find("limit")
            efforts[joint.get("name", "")] = float(limit.get("effort", "0")) if limit is not None else 0.0

    ET.indent(root, space="  ")
    text = ET.tostring(root, encoding="unicode")
    mj_root = ET.fromstring(text)
    mj_root.insert(0, ET.fromstring(f"<mujoco>{MUJOCO_COMPILER}</mujoco>"))
    mujoco_text = ET.tostring(mj_root, encoding="unicode")

    srdf = parse_srdf(source_path(cfg, cfg.srdf).read_text()) if cfg.srdf else None
    return PreparedUrdf(text, mujoco_text, tuple(links), efforts, srdf)


def with_extra_frames(urdf_text: str, frames: dict[str, tuple[str, np.ndarray]]) -> str:
    """URDF text with massless fixed links added: ``{name: (parent_link, 4x4 transform)}``.

    placo's humanoid helpers look frames up by name (left_foot, right_foot, trunk).
    """
    from scipy.spatial.transform import Rotation

    root = ET.fromstring(urdf_text)
    existing = {link.get("name") for link in root.findall("link")}
    for name, (parent, pose) in frames.items():
        if name in existing:
            continue
        ET.SubElement(root, "link", {"name": name})
        joint = ET.SubElement(root, "joint", {"name": f"{name}_frame_joint", "type": "fixed"})
        rpy = Rotation.from_matrix(pose[:3, :3]).as_euler("xyz")
        ET.SubElement(joint, "origin", {"xyz": " ".join(repr(float(v)) for v in pose[:3, 3]),
                                        "rpy": " ".join(repr(float(v)) for v in rpy)})
        ET.SubElement(joint, "parent", {"link": parent})
        ET.SubElement(joint, "child", {"link": name})
    return ET.tostring(root, encoding="unicode")
