"""Generate the project-made bipedal dinosaur (robots/dino/): URDF + STL meshes from trimesh primitives.

Run ``.venv/bin/python tools/make_dino.py`` to regenerate ``robots/dino/dino.urdf`` and
``robots/dino/meshes/*.stl``. The output is deterministic (same bytes every run), so the
shipped files can be checked against the script (tests/test_dino.py).

The character follows the small-scale dinosaur of the paper (§8.1, Table 4: 615 mm, 16.9 kg,
20 actuators): a horizontal body carried over two 6-DoF legs (hip yaw/roll/pitch, knee, ankle
pitch/roll) with flat feet, a 3-joint neck with a head (neck pitch, neck yaw, head pitch: the
bird-like bob), a 3-joint segmented tail with alternating yaw and pitch joints, and two small
1-DoF arms. Every link is a union of primitives, each with its own mass; a link's inertia is
the sum of the primitives' trimesh mass properties moved to the link's centre of mass.
Actuator limits are sized like the small quasi-direct-drive actuators of robots of this mass
(legs 25–60 N·m, 15–20 rad/s; neck/tail 6–10 N·m).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "robots" / "dino"

# ----------------------------------------------------------------------------- dimensions (m)

HIP_Y_M = 0.075  # hip joints either side of the pelvis
HIP_Z_M = -0.03
THIGH_M = 0.18
SHANK_M = 0.18
ANKLE_TO_SOLE_M = 0.04
SOLE_LENGTH_M = 0.15
SOLE_WIDTH_M = 0.1
SOLE_X_M = 0.025  # sole centre ahead of the ankle
SOLE_THICKNESS_M = 0.02

BODY_COLOR = (0.36, 0.55, 0.33, 1.0)
BELLY_COLOR = (0.78, 0.74, 0.55, 1.0)
LIMB_COLOR = (0.30, 0.47, 0.28, 1.0)
FOOT_COLOR = (0.25, 0.25, 0.22, 1.0)


@dataclass
class Part:
    """One primitive of a link, in the link frame, with its own mass."""

    mesh: trimesh.Trimesh
    mass_kg: float


@dataclass
class Link:
    name: str
    parts: list[Part]
    color: tuple[float, float, float, float] = LIMB_COLOR


@dataclass
class Joint:
    name: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    axis: tuple[float, float, float]
    lower: float
    upper: float
    effort: float  # N·m
    velocity: float  # rad/s


@dataclass
class Robot:
    links: list[Link] = field(default_factory=list)
    joints: list[Joint] = field(default_factory=list)


# ----------------------------------------------------------------------------- primitives


def _placed(mesh: trimesh.Trimesh, xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    mat = trimesh.transformations.euler_matrix(*rpy, axes="sxyz")
    mat[:3, 3] = xyz
    mesh = mesh.copy()
    mesh.apply_transform(mat)
    return mesh


def ellipsoid(radii, xyz=(0, 0, 0), rpy=(0, 0, 0), subdivisions: int = 2) -> trimesh.Trimesh:
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    sphere.apply_scale(radii)
    return _placed(sphere, xyz, rpy)


def capsule_between(a, b, radius: float, count=(12, 12)) -> trimesh.Trimesh:
    """A capsule whose axis runs from point ``a`` to point ``b`` (link frame)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = b - a
    length = float(np.linalg.norm(d))
    cap = trimesh.creation.capsule(height=length, radius=radius, count=list(count))
    # trimesh's capsule lies along z, centred on the origin (trimesh 4–5; centred here whatever the
    # version does): placed at the segment's midpoint. (Placed at ``a``, the first model's thighs,
    # shanks and tail reached half a segment past their joints: the thighs rubbed on the tail.)
    cap.apply_translation([0.0, 0.0, -0.5 * float(cap.bounds[0, 2] + cap.bounds[1, 2])])
    z = d / length
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(ref, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    mat = np.eye(4)
    mat[:3, :3] = np.column_stack([x, y, z])
    mat[:3, 3] = 0.5 * (a + b)
    cap.apply_transform(mat)
    return cap


def box(extents, xyz=(0, 0, 0), rpy=(0, 0, 0)) -> trimesh.Trimesh:
    return _placed(trimesh.creation.box(extents=extents), xyz, rpy)


def cone_between(a, b, radius: float, sections: int = 16) -> trimesh.Trimesh:
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = b - a
    length = float(np.linalg.norm(d))
    cone = trimesh.creation.cone(radius=radius, height=length, sections=sections)
    z = d / length
    ref = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(ref, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    mat = np.eye(4)
    mat[:3, :3] = np.column_stack([x, y, z])
    mat[:3, 3] = a
    cone.apply_transform(mat)
    return cone


# ----------------------------------------------------------------------------- the character


def build() -> Robot:
    r = Robot()
    # Pelvis = the horizontal body (root link): belly, chest and hips in one rigid trunk.
    r.links.append(Link("pelvis", [
        Part(ellipsoid((0.17, 0.085, 0.085), xyz=(0.0, 0.0, 0.05), subdivisions=3), 6.0),
        Part(ellipsoid((0.08, 0.07, 0.06), xyz=(0.12, 0.0, 0.09), rpy=(0.0, -0.5, 0.0)), 1.0),
        Part(ellipsoid((0.07, 0.1, 0.045), xyz=(-0.02, 0.0, -0.01)), 0.6),
    ], BODY_COLOR))

    for side, sy in (("left", 1.0), ("right", -1.0)):
        y = sy * HIP_Y_M
        r.links += [
            Link(f"{side}_hip_yaw_link", [Part(capsule_between((0, 0, 0.04), (0, 0, 0.0), 0.03), 0.35)]),
            Link(f"{side}_hip_roll_link", [Part(ellipsoid((0.045, 0.035, 0.035)), 0.3)]),
            Link(f"{side}_hip_pitch_link", [  # the thigh
                Part(capsule_between((0.0, 0.0, 0.0), (0.0, 0.0, -THIGH_M), 0.04), 1.2),
                Part(ellipsoid((0.07, 0.05, 0.06), xyz=(0.015, 0.0, -0.05)), 0.5),
            ], BODY_COLOR),
            Link(f"{side}_knee_link", [  # the shank
                Part(capsule_between((0.0, 0.0, 0.0), (0.0, 0.0, -SHANK_M), 0.028), 0.75),
            ]),
            Link(f"{side}_ankle_pitch_link", [Part(ellipsoid((0.025, 0.03, 0.025)), 0.1)]),
            Link(f"{side}_ankle_roll_link", [  # the foot: a flat sole plate with three toes
                Part(box((SOLE_LENGTH_M, SOLE_WIDTH_M, SOLE_THICKNESS_M),
                         xyz=(SOLE_X_M, 0.0, -ANKLE_TO_SOLE_M + 0.5 * SOLE_THICKNESS_M)), 0.25),
                Part(capsule_between((0.0, 0.0, -0.005), (0.0, 0.0, -ANKLE_TO_SOLE_M + SOLE_THICKNESS_M), 0.022), 0.08),
                *[Part(cone_between((SOLE_X_M + 0.06, dy, -ANKLE_TO_SOLE_M + 0.01),
                                    (SOLE_X_M + 0.1, 1.3 * dy, -ANKLE_TO_SOLE_M + 0.006), 0.009), 0.01)
                  for dy in (-0.025, 0.0, 0.025)],
            ], FOOT_COLOR),
        ]
        r.joints += [
            Joint(f"{side}_hip_yaw_joint", "pelvis", f"{side}_hip_yaw_link", (0.0, y, HIP_Z_M), (0, 0, 1),
                  -0.6, 0.6, 30.0, 20.0),
            Joint(f"{side}_hip_roll_joint", f"{side}_hip_yaw_link", f"{side}_hip_roll_link", (0.0, 0.0, 0.0), (1, 0, 0),
                  -0.5 if sy > 0 else -0.8, 0.8 if sy > 0 else 0.5, 50.0, 20.0),
            Joint(f"{side}_hip_pitch_joint", f"{side}_hip_roll_link", f"{side}_hip_pitch_link", (0.0, 0.0, 0.0),
                  (0, 1, 0), -1.8, 1.0, 60.0, 20.0),
            Joint(f"{side}_knee_joint", f"{side}_hip_pitch_link", f"{side}_knee_link", (0.0, 0.0, -THIGH_M), (0, 1, 0),
                  0.0, 2.4, 80.0, 16.0),
            Joint(f"{side}_ankle_pitch_joint", f"{side}_knee_link", f"{side}_ankle_pitch_link", (0.0, 0.0, -SHANK_M),
                  (0, 1, 0), -1.0, 0.7, 30.0, 20.0),
            Joint(f"{side}_ankle_roll_joint", f"{side}_ankle_pitch_link", f"{side}_ankle_roll_link", (0.0, 0.0, 0.0),
                  (1, 0, 0), -0.4, 0.4, 20.0, 20.0),
        ]

    # Neck (pitch at the shoulders, yaw mid-neck, head pitch): the bird-like bob.
    r.links += [
        Link("neck_pitch_link", [Part(capsule_between((0.0, 0.0, 0.0), (0.05, 0.0, 0.08), 0.035), 0.45)], BODY_COLOR),
        Link("neck_yaw_link", [Part(capsule_between((0.0, 0.0, 0.0), (0.04, 0.0, 0.07), 0.03), 0.3)], BODY_COLOR),
        Link("head_link", [
            Part(ellipsoid((0.065, 0.045, 0.045), xyz=(0.04, 0.0, 0.0)), 0.4),
            Part(ellipsoid((0.06, 0.03, 0.025), xyz=(0.11, 0.0, -0.015)), 0.15),
            *[Part(ellipsoid((0.012, 0.01, 0.012), xyz=(0.06, s * 0.04, 0.02)), 0.005) for s in (1.0, -1.0)],
        ], BODY_COLOR),
    ]
    r.joints += [
        Joint("neck_pitch_joint", "pelvis", "neck_pitch_link", (0.16, 0.0, 0.12), (0, 1, 0), -0.8, 0.8, 10.0, 15.0),
        Joint("neck_yaw_joint", "neck_pitch_link", "neck_yaw_link", (0.05, 0.0, 0.08), (0, 0, 1), -0.8, 0.8, 6.0, 15.0),
        Joint("head_pitch_joint", "neck_yaw_link", "head_link", (0.04, 0.0, 0.07), (0, 1, 0), -0.8, 0.8, 4.0, 15.0),
    ]

    # Tail: alternating yaw, pitch, yaw segments, tapering.
    r.links += [
        Link("tail_1_link", [Part(capsule_between((0.0, 0.0, 0.0), (-0.15, 0.0, 0.0), 0.045), 0.5)], BODY_COLOR),
        Link("tail_2_link", [Part(capsule_between((0.0, 0.0, 0.0), (-0.14, 0.0, 0.0), 0.032), 0.3)], BODY_COLOR),
        Link("tail_3_link", [Part(cone_between((0.0, 0.0, 0.0), (-0.16, 0.0, 0.0), 0.024), 0.15)], BODY_COLOR),
    ]
    r.joints += [
        Joint("tail_yaw_1_joint", "pelvis", "tail_1_link", (-0.15, 0.0, 0.06), (0, 0, 1), -0.6, 0.6, 10.0, 15.0),
        Joint("tail_pitch_2_joint", "tail_1_link", "tail_2_link", (-0.15, 0.0, 0.0), (0, 1, 0), -0.6, 0.6, 8.0, 15.0),
        Joint("tail_yaw_3_joint", "tail_2_link", "tail_3_link", (-0.14, 0.0, 0.0), (0, 0, 1), -0.6, 0.6, 6.0, 15.0),
    ]

    # Small arms under the chest (shoulder pitch only).
    for side, sy in (("left", 1.0), ("right", -1.0)):
        r.links.append(Link(f"{side}_arm_link", [
            Part(capsule_between((0.0, 0.0, 0.0), (0.03, 0.0, -0.07), 0.014), 0.1),
            Part(capsule_between((0.03, 0.0, -0.07), (0.075, 0.0, -0.08), 0.011), 0.05),
        ]))
        r.joints.append(Joint(f"{side}_shoulder_pitch_joint", "pelvis", f"{side}_arm_link",
                              (0.17, sy * 0.065, 0.05), (0, 1, 0), -1.2, 1.2, 5.0, 15.0))
    return r


# ----------------------------------------------------------------------------- mass properties


def link_inertial(link: Link) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre of mass, inertia about the centre of mass) of a link's primitives."""
    mass = sum(p.mass_kg for p in link.parts)
    coms, inertias = [], []
    for p in link.parts:
        mesh = p.mesh
        volume = float(mesh.volume)
        if not mesh.is_watertight or volume <= 0:
            raise ValueError(f"{link.name}: a primitive is not a closed solid")
        props = trimesh.triangles.mass_properties(mesh.triangles, density=p.mass_kg / volume)
        coms.append(np.asarray(props["center_mass"]))
        inertias.append(np.asarray(props["inertia"]))  # about the part's own centre of mass
    com = sum(p.mass_kg * c for p, c in zip(link.parts, coms)) / mass
    inertia = np.zeros((3, 3))
    for p, c, i in zip(link.parts, coms, inertias):
        d = c - com
        inertia += i + p.mass_kg * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return mass, com, inertia


# ----------------------------------------------------------------------------- output


def _f(x: float) -> str:
    v = round(float(x), 9)
    return "0" if v == 0 else repr(v)


def _v(xs) -> str:
    return " ".join(_f(x) for x in xs)


def urdf_text(robot: Robot) -> str:
    lines = ['<?xml version="1.0"?>',
             "<!-- Generated by tools/make_dino.py: do not edit by hand. -->",
             '<robot name="dino">']
    for link in robot.links:
        mass, com, inertia = link_inertial(link)
        rgba = _v(link.color)
        lines += [
            f'  <link name="{link.name}">',
            "    <inertial>",
            f'      <origin xyz="{_v(com)}" rpy="0 0 0"/>',
            f'      <mass value="{_f(mass)}"/>',
            f'      <inertia ixx="{_f(inertia[0, 0])}" ixy="{_f(inertia[0, 1])}" ixz="{_f(inertia[0, 2])}" '
            f'iyy="{_f(inertia[1, 1])}" iyz="{_f(inertia[1, 2])}" izz="{_f(inertia[2, 2])}"/>',
            "    </inertial>",
            "    <visual>",
            '      <origin xyz="0 0 0" rpy="0 0 0"/>',
            f'      <geometry><mesh filename="meshes/{link.name}.stl"/></geometry>',
            f'      <material name="{link.name}_color"><color rgba="{rgba}"/></material>',
            "    </visual>",
            "    <collision>",
            '      <origin xyz="0 0 0" rpy="0 0 0"/>',
            f'      <geometry><mesh filename="meshes/{link.name}.stl"/></geometry>',
            "    </collision>",
            "  </link>",
        ]
    for j in robot.joints:
        lines += [
            f'  <joint name="{j.name}" type="revolute">',
            f'    <origin xyz="{_v(j.xyz)}" rpy="0 0 0"/>',
            f'    <parent link="{j.parent}"/>',
            f'    <child link="{j.child}"/>',
            f'    <axis xyz="{_v(j.axis)}"/>',
            f'    <limit lower="{_f(j.lower)}" upper="{_f(j.upper)}" effort="{_f(j.effort)}" velocity="{_f(j.velocity)}"/>',
            "  </joint>",
        ]
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def link_mesh(link: Link) -> trimesh.Trimesh:
    mesh = trimesh.util.concatenate([p.mesh for p in link.parts])
    mesh.vertices = np.round(mesh.vertices, 7)
    return mesh


def stl_bytes(mesh: trimesh.Trimesh) -> bytes:
    """Binary STL with a fixed header (trimesh's exporter is deterministic given the arrays)."""
    tris = np.asarray(mesh.triangles, dtype=np.float32)
    normals = np.asarray(mesh.face_normals, dtype=np.float32)
    header = b"motion-studio dino (tools/make_dino.py)".ljust(80, b" ")
    rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"] = normals
    rec["v"] = tris
    return header + np.uint32(len(tris)).tobytes() + rec.tobytes()


def write(out: Path = OUT) -> list[Path]:
    robot = build()
    written = []
    (out / "meshes").mkdir(parents=True, exist_ok=True)
    for link in robot.links:
        path = out / "meshes" / f"{link.name}.stl"
        path.write_bytes(stl_bytes(link_mesh(link)))
        written.append(path)
    path = out / "dino.urdf"
    path.write_text(urdf_text(robot))
    written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help="output folder (default robots/dino)")
    args = parser.parse_args(argv)
    paths = write(args.out)
    robot = build()
    total = sum(link_inertial(link)[0] for link in robot.links)
    print(f"wrote {len(paths)} files to {args.out} ({len(robot.joints)} joints, {total:.2f} kg)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
