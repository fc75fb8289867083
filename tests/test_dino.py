"""The project-made dinosaur: the shipped files are what tools/make_dino.py makes, and its figures."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from engine.robot.config import robots_dir
from engine.robot.model import load_robot

REPO = Path(__file__).resolve().parents[1]


def _make_dino():
    spec = importlib.util.spec_from_file_location("make_dino", REPO / "tools" / "make_dino.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["make_dino"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_script_is_deterministic_and_matches_the_shipped_files(tmp_path):
    make_dino = _make_dino()
    first = make_dino.write(tmp_path / "a")
    second = make_dino.write(tmp_path / "b")
    shipped = robots_dir() / "dino"
    assert len(first) == len(second) == len(list((shipped / "meshes").glob("*.stl"))) + 1
    for a, b in zip(first, second):
        rel = a.relative_to(tmp_path / "a")
        assert a.read_bytes() == b.read_bytes(), rel
        assert a.read_bytes() == (shipped / rel).read_bytes(), f"{rel}: rerun tools/make_dino.py"


def test_inertias_are_the_primitives_mass_properties():
    """A single-primitive link: the URDF inertia is trimesh's solid inertia at that mass."""
    make_dino = _make_dino()
    robot = make_dino.build()
    knee = next(link for link in robot.links if link.name == "left_knee_link")
    assert len(knee.parts) == 1
    mass, com, inertia = make_dino.link_inertial(knee)
    part = knee.parts[0]
    mesh = part.mesh.copy()
    mesh.density = part.mass_kg / mesh.volume
    np.testing.assert_allclose(mass, mesh.mass)
    np.testing.assert_allclose(com, mesh.center_mass, atol=1e-9)
    np.testing.assert_allclose(inertia, mesh.moment_inertia, rtol=1e-9, atol=1e-12)
    # Capsule along z: the two transverse moments are equal and larger than the axial one.
    assert inertia[0, 0] == pytest.approx(inertia[1, 1]) and inertia[2, 2] < inertia[0, 0]


def test_dino_figures():
    dino = load_robot("dino")
    assert 16.0 <= dino.mass_kg <= 18.0
    assert 0.6 <= dino.height_m <= 0.8
    assert dino.n_joints == 20  # the paper's dino has 20 actuators (Table 4)
    names = set(dino.joint_names)
    for side in ("left", "right"):
        for j in ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll"):
            assert f"{side}_{j}_joint" in names
    upper = set(dino.config.upper_body_joints)
    assert {"neck_pitch_joint", "neck_yaw_joint", "head_pitch_joint"} <= upper
    assert {"tail_yaw_1_joint", "tail_pitch_2_joint", "tail_yaw_3_joint"} <= upper
    assert np.all(dino.effort_limits > 0) and np.all(dino.effort_limits <= 100)
    armature = dino.mj_model.dof_armature[dino.mj_dof_index]
    assert np.all(armature > 0)
    # Every body has a physically valid inertia (principal moments obey the triangle rule).
    for bid in range(1, dino.mj_model.nbody):
        moments = np.sort(dino.mj_model.body_inertia[bid])
        assert moments[0] > 0 and moments[2] <= moments[0] + moments[1] + 1e-12


def test_limb_segments_run_from_joint_to_joint():
    """A capsule primitive spans its segment (plus its radius at both ends), whatever trimesh version
    made it: the first model's capsules were centred on their first joint, so the thighs reached
    half a thigh above the hip and rubbed on the tail while walking (slipping feet)."""
    make_dino = _make_dino()
    robot = make_dino.build()
    links = {link.name: link for link in robot.links}
    shank = links["left_knee_link"].parts[0].mesh  # knee (origin) to ankle, radius 0.028
    np.testing.assert_allclose(shank.bounds[:, 2], [-make_dino.SHANK_M - 0.028, 0.028], atol=1e-6)
    tail = links["tail_1_link"].parts[0].mesh  # tail joint (origin) back 0.15 m, radius 0.045
    np.testing.assert_allclose(tail.bounds[:, 0], [-0.15 - 0.045, 0.045], atol=1e-6)


def test_tail_swings_clear_of_the_legs():
    """Standing legs, the tail anywhere in its yaw range (the strut style swings it): no body touches
    another (the first model's tail hit the thighs from ±0.3 rad, so every strafe step was pushed)."""
    import mujoco

    dino = load_robot("dino")
    model = dino.mj_model
    data = mujoco.MjData(model)
    floor = model.geom("floor").id
    tail = model.joint("tail_yaw_1_joint").qposadr[0]
    for yaw in np.linspace(-0.6, 0.6, 7):
        qpos = dino.mj_standing_qpos().copy()
        qpos[2] += 0.05  # clear of the floor
        qpos[tail] = yaw
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        touching = [(model.body(int(model.geom_bodyid[c.geom1])).name, model.body(int(model.geom_bodyid[c.geom2])).name)
                    for c in data.contact[:data.ncon] if floor not in (c.geom1, c.geom2)]
        assert touching == [], f"tail yaw {yaw:.2f}: {touching}"
