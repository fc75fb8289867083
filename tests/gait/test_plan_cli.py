"""`studio plan` as a user runs it: every shipped style through the sweep, bad input refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

from engine.gait.command_schedule import CommandError, parse_command
from engine.gait.style import load_style
from tests.conftest import REPO, run_studio

SHIPPED = sorted((REPO / "styles").glob("*/*.json"))


def _shipped_param(path):
    return pytest.param(path, id=f"{path.parent.name}/{path.stem}")


@pytest.fixture(scope="module")
def plans(tmp_path_factory):
    out = {}
    folder = tmp_path_factory.mktemp("plans")
    for path in SHIPPED:
        robot, name = path.parent.name, path.stem
        npz = folder / f"{robot}_{name}.npz"
        done = run_studio("plan", "--robot", robot, "--style", name, "--command", "sweep", "--duration", "56",
                          "--out", str(npz))
        assert done.returncode == 0, done.stderr
        out[(robot, name)] = np.load(npz)
    return out


@pytest.mark.parametrize("path", [_shipped_param(p) for p in SHIPPED])
def test_sweep_plan_has_the_documented_fields_and_properties(plans, path):
    robot, name = path.parent.name, path.stem
    z = plans[(robot, name)]
    n = len(z["t"])
    assert n == 56 * 125
    k = len(z["upper_joint_names"])
    shapes = {"phase": (n,), "command": (n, 3), "contact": (n, 2), "foot_pos": (n, 2, 3), "foot_quat": (n, 2, 4),
              "sole_corners": (n, 2, 4, 3), "pelvis_z": (n,), "pelvis_quat": (n, 4), "upper_q": (n, k),
              "sample_weights": (n, 9), "sample_names": (9,)}
    for key, shape in shapes.items():
        assert z[key].shape == shape, key
    assert z["qpos"].shape[0] == n and z["contact"].dtype == bool
    np.testing.assert_allclose(np.linalg.norm(z["foot_quat"], axis=2), 1.0, atol=1e-9)
    # No sole corner below the ground; flat feet never slip; feet land on their footholds.
    assert z["sole_corners"][..., 2].min() >= -1e-4
    for i in range(2):
        flat = np.all(z["sole_corners"][:, i, :, 2] == 0.0, axis=1) & z["contact"][:, i]
        both = flat[1:] & flat[:-1]
        step = np.linalg.norm(np.diff(z["foot_pos"][:, i], axis=0), axis=1)
        assert step[both].max(initial=0.0) == 0.0
        landed = np.where(z["contact"][1:, i] & ~z["contact"][:-1, i])[0] + 1
        assert len(landed) > 20
        np.testing.assert_allclose(z["foot_pos"][landed, i, :2], z["footholds"][landed, i, :2], atol=1e-9)
    # The kinematic preview realises the reference.
    assert np.percentile(z["ik_error_m"], 99) < 5e-3
    # Weights are convex; the sweep reaches the style's limits in every direction.
    assert np.allclose(z["sample_weights"].sum(axis=1), 1.0) and (z["sample_weights"] >= 0).all()
    style = load_style(path)
    v = style.velocities
    cmd = z["command"]
    assert cmd[:, 0].max() == pytest.approx(v.x_max_mps) and cmd[:, 0].min() == pytest.approx(-v.x_slow_mps)
    assert cmd[:, 1].max() == pytest.approx(v.y_max_mps) and cmd[:, 1].min() == pytest.approx(-v.y_max_mps)
    assert cmd[:, 2].max() == pytest.approx(v.yaw_max_radps) and cmd[:, 2].min() == pytest.approx(-v.yaw_max_radps)
    assert np.abs(cmd[-1]).max() == 0.0  # stops


def test_neutral_reaches_the_animators_speeds(plans):
    cmd = plans[("g1", "neutral")]["command"]
    assert cmd[:, 0].max() >= 0.5 and cmd[:, 1].max() >= 0.15 and cmd[:, 2].max() >= 1.0


def _broken(tmp_path, mutate) -> str:
    doc = json.loads((REPO / "styles/g1/neutral.json").read_text())
    mutate(doc)
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(doc, allow_nan=True))
    return str(path)


@pytest.mark.parametrize(("mutate", "field"), [
    (lambda d: d["samples"]["in_place"]["intervals"].__setitem__("right_swing_s", [0.1, 0.3]), "samples.in_place.intervals"),
    # each case is a `studio plan` process: three more in the slow tier (the fields themselves: tests/gait/test_style.py)
    pytest.param(lambda d: d["samples"]["in_place"]["curves"].__setitem__("joints.left_elbw_joint", {"knots": [[0, 0.5]]}),
                 "samples.in_place.curves.joints.left_elbw_joint", marks=pytest.mark.slow),
    pytest.param(lambda d: d["samples"]["forward_fast"]["attributes"].__setitem__("stance_width_m", float("nan")),
                 "samples.forward_fast.attributes.stance_width_m", marks=pytest.mark.slow),
    pytest.param(lambda d: d["samples"].pop("right_strafe"), "samples.right_strafe", marks=pytest.mark.slow),
    (lambda d: d.__setitem__("robot", "talos"), "robot"),
])
def test_malformed_style_exits_2_naming_the_field(tmp_path, mutate, field):
    path = _broken(tmp_path, mutate)
    out = run_studio("plan", "--robot", "g1", "--style", path, "--duration", "1", "--out", str(tmp_path / "x.npz"))
    assert out.returncode == 2 and "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and f"broken.json: {field}: expected" in lines[0] or f"broken.json: {field}: missing" in lines[0]
    assert not (tmp_path / "x.npz").exists()


@pytest.mark.slow  # seven `studio plan` processes; the spec parsing itself: test_command_specs_parse below
def test_command_specs(tmp_path):
    frames = tmp_path / "keys.json"
    frames.write_text(json.dumps({"keyframes": [[0, 0, 0, 0], [1, 0.2, 0, 0], [2, 0.2, 0, 0.4]]}))
    out = run_studio("plan", "--style", "neutral", "--command", str(frames), "--duration", "3", "--out", str(tmp_path / "k.npz"))
    assert out.returncode == 0, out.stderr
    z = np.load(tmp_path / "k.npz")
    assert z["command"][-1] == pytest.approx([0.2, 0.0, 0.4])
    out = run_studio("plan", "--command", "0.1,0,0", "--duration", "1", "--out", str(tmp_path / "c.npz"))
    assert out.returncode == 0 and np.load(tmp_path / "c.npz")["command"][-1] == pytest.approx([0.1, 0, 0])
    for spec, message in (("fly", "neither vx,vy,wz, a preset"), ("1,2", "expected three finite numbers"),
                          ("50,0,0", None)):
        out = run_studio("plan", "--command", spec, "--duration", "1", "--out", str(tmp_path / "e.npz"))
        if message is None:  # impossible velocity: clamped with a note, not an error
            assert out.returncode == 0 and "clamped to the style's limits" in out.stdout
        else:
            assert out.returncode == 2 and message in out.stderr
    out = run_studio("plan", "--robot", "go1", "--duration", "1", "--out", str(tmp_path / "q.npz"))
    assert out.returncode == 2 and "expected a biped" in out.stderr
    out = run_studio("plan", "--style", "nosuch", "--duration", "1", "--out", str(tmp_path / "q.npz"))
    assert out.returncode == 2 and "unknown style 'nosuch' for g1; styles: casual, injured, neutral, sneak" in out.stderr


def test_command_specs_parse(tmp_path):
    """The --command specs of test_command_specs (slow: it runs `studio plan`), parsed in process: a keyframe
    file is interpolated and held after its last frame, vx,vy,wz is constant, bad specs name what they expect."""
    velocities = load_style(REPO / "styles/g1/neutral.json").velocities
    frames = tmp_path / "keys.json"
    frames.write_text(json.dumps({"keyframes": [[0, 0, 0, 0], [1, 0.2, 0, 0], [2, 0.2, 0, 0.4]]}))
    schedule = parse_command(str(frames), velocities)
    assert schedule(0.5) == pytest.approx([0.1, 0.0, 0.0]) and schedule(1.5) == pytest.approx([0.2, 0.0, 0.2])
    assert schedule(3.0) == pytest.approx([0.2, 0.0, 0.4]) and schedule.end_s == 2.0
    constant = parse_command("0.1,0,0", velocities)
    assert constant(0.0) == pytest.approx([0.1, 0, 0]) and constant(5.0) == pytest.approx([0.1, 0, 0])
    for spec, message in (("fly", "neither vx,vy,wz, a preset"), ("1,2", "expected three finite numbers")):
        with pytest.raises(CommandError, match=message):
            parse_command(spec, velocities, cwd=tmp_path)
