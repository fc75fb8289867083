"""Robot config files: every shipped one loads; malformed ones fail with one precise line."""

from __future__ import annotations

from pathlib import Path

import pytest

from engine.robot.config import RobotConfigError, load_config, load_robot_config, robot_names, robots_dir

EXPECTED = {"g1", "talos", "dino", "go1", "go2", "a1", "b1", "anymal_c", "human"}


def test_library_has_the_nine_robots_default_first():
    names = robot_names()
    assert set(names) == EXPECTED
    assert names[0] == "g1"


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_every_config_loads(name):
    cfg = load_robot_config(name)
    assert cfg.name == name
    if cfg.kind == "biped":
        assert set(cfg.soles) == {"left", "right"}
        assert cfg.upper_body_joints
    elif cfg.kind == "quadruped":
        assert len(cfg.feet) == 4
    else:
        assert not cfg.simulated


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _without(field_line: str) -> str:
    text = (robots_dir() / "g1.toml").read_text()
    assert field_line in text
    return text.replace(field_line, "")


@pytest.mark.parametrize(
    ("removed", "field"),
    [('kind = "biped"\n', "kind"), ('root_link = "pelvis"\n', "model.root_link"), ("sole_length_m = 0.17\n", "feet.left.sole_length_m")],
)
def test_missing_field_names_file_and_field(tmp_path, removed, field):
    text = _without(removed)
    path = _write(tmp_path, "g1", text)
    with pytest.raises(RobotConfigError) as err:
        load_config(path)
    line = str(err.value)
    assert "\n" not in line
    assert line.startswith("g1.toml: ") and f" {field}: " in line and "missing" in line


def test_wrong_type_and_unknown_field(tmp_path):
    text = (robots_dir() / "g1.toml").read_text()
    with pytest.raises(RobotConfigError, match=r"g1.toml: feet.left.sole_width_m: expected a number"):
        load_config(_write(tmp_path, "g1", text.replace("sole_width_m = 0.055", 'sole_width_m = "wide"', 1)))
    with pytest.raises(RobotConfigError, match=r"g1.toml: model.rot_link: unknown field \(did you mean 'root_link'\?\)"):
        load_config(_write(tmp_path, "g1", text.replace("root_link", "rot_link")))
    with pytest.raises(RobotConfigError, match=r"g1.toml: expected valid TOML"):
        load_config(_write(tmp_path, "g1", text + "\n[[[broken"))


def test_unknown_robot_lists_known_names():
    with pytest.raises(RobotConfigError) as err:
        load_robot_config("g11")
    text = str(err.value)
    assert "unknown robot 'g11'" in text and "talos" in text and "Did you mean 'g1'" in text
    with pytest.raises(RobotConfigError):
        load_robot_config("../robots/g1")  # no path tricks


def test_unknown_source_package_names_the_field(tmp_path):
    text = (robots_dir() / "dino.toml").read_text().replace('package = "local"', 'package = "elsewhere"')
    with pytest.raises(RobotConfigError) as err:
        load_config(_write(tmp_path, "dino", text))
    assert str(err.value).startswith("dino.toml: source.package: expected one of example-robot-data, local")


def test_local_source_is_read_next_to_the_config(tmp_path):
    """A project-made robot's URDF and meshes resolve relative to its config file's folder."""
    from engine.robot.urdf import mesh_sources, source_path

    cfg = load_robot_config("dino")
    assert source_path(cfg, cfg.urdf) == robots_dir() / "dino" / "dino.urdf"
    meshes = mesh_sources(cfg)
    assert meshes and all(m.is_file() and m.parent == robots_dir() / "dino" / "meshes" for m in meshes)
    moved = _write(tmp_path, "dino", (robots_dir() / "dino.toml").read_text())
    with pytest.raises(RobotConfigError) as err:
        source_path(load_config(moved), "dino/dino.urdf")
    assert "dino.toml: source.urdf: dino/dino.urdf not found" in str(err.value)


def test_gait_feedback_gains_come_from_the_config(tmp_path, monkeypatch):
    from engine.control.gait_feedback import GaitFeedbackGains

    assert GaitFeedbackGains.for_robot("g1") == GaitFeedbackGains(kappa_single=(0.75, 1.6))  # g1.toml's one gain
    dino = GaitFeedbackGains.for_robot("dino")
    assert dino.velocity_cutoff_hz == load_robot_config("dino").gait_feedback["velocity_cutoff_hz"] == 0.5
    assert dino.step_max_m == load_robot_config("dino").gait_feedback["step_max_m"] == 0.2
    assert dino.time_kp_per_m == GaitFeedbackGains().time_kp_per_m  # what the table leaves out keeps its default
    text = (robots_dir() / "dino.toml").read_text()
    _write(tmp_path, "dino", text.replace("velocity_kd = 0.8", "velocity_kd = 0.8\nkappa_single = [0.7, 1.5]"))
    monkeypatch.setenv("MOTION_STUDIO_ROBOTS", str(tmp_path))
    assert GaitFeedbackGains.for_robot("dino").kappa_single == (0.7, 1.5)
    _write(tmp_path, "dino", text.replace("velocity_kd = 0.8", "velocity_kdd = 0.8"))
    with pytest.raises(RobotConfigError, match=r"^dino.toml: control.gait_feedback.velocity_kdd: unknown gain"):
        GaitFeedbackGains.for_robot("dino")
    _write(tmp_path, "dino", text.replace("velocity_kd = 0.8", "velocity_kd = [0.8, 0.9]"))
    with pytest.raises(RobotConfigError, match=r"control.gait_feedback.velocity_kd: expected a number"):
        GaitFeedbackGains.for_robot("dino")
    _write(tmp_path, "dino", text.replace("velocity_kd = 0.8", "velocity_kd = -1"))
    with pytest.raises(RobotConfigError, match=r"control.gait_feedback.velocity_kd: expected a non-negative"):
        load_config(tmp_path / "dino.toml")


def test_curve_rate_bounds_come_from_the_config(tmp_path):
    """[gait.curve_rates]: typed, positive; a field left out (or the whole table, TALOS) keeps its default."""
    from engine.robot.config import CurveRateLimits

    assert load_robot_config("talos").gait.curve_rates == CurveRateLimits()
    g1 = load_robot_config("g1").gait.curve_rates
    assert g1.foot_angle_radps == 3.8 and g1.joint_max_radps == 2.2
    text = (robots_dir() / "g1.toml").read_text()
    assert "foot_angle_radps = 3.8\n" in text
    cfg = load_config(_write(tmp_path, "g1", text.replace("foot_angle_radps = 3.8\n", "")))
    assert cfg.gait.curve_rates.foot_angle_radps == CurveRateLimits().foot_angle_radps
    with pytest.raises(RobotConfigError, match=r"^g1.toml: gait.curve_rates.foot_angle_radps: expected a positive number"):
        load_config(_write(tmp_path, "g1", text.replace("foot_angle_radps = 3.8", "foot_angle_radps = 0")))
    with pytest.raises(RobotConfigError, match=r"^g1.toml: gait.curve_rates.foot_angle_radps: expected a number"):
        load_config(_write(tmp_path, "g1", text.replace("foot_angle_radps = 3.8", 'foot_angle_radps = "fast"')))
    with pytest.raises(RobotConfigError, match=r"gait.curve_rates.foot_angle_rps: unknown field \(did you mean 'foot_angle_radps'\?\)"):
        load_config(_write(tmp_path, "g1", text.replace("foot_angle_radps = 3.8", "foot_angle_rps = 3.8")))


def test_puppet_clearance_comes_from_the_config(tmp_path):
    """[upper_body] puppet_clearance_m: metres in [0, 0.1]; left out (TALOS) it is 1 cm."""
    assert load_robot_config("talos").puppet_clearance_m == 0.01
    assert load_robot_config("g1").puppet_clearance_m == 0.015
    text = (robots_dir() / "g1.toml").read_text()
    assert "puppet_clearance_m = 0.015\n" in text
    assert load_config(_write(tmp_path, "g1", text.replace("puppet_clearance_m = 0.015\n", ""))).puppet_clearance_m == 0.01
    with pytest.raises(RobotConfigError, match=r"^g1.toml: upper_body.puppet_clearance_m: expected metres in \[0, 0.1\]"):
        load_config(_write(tmp_path, "g1", text.replace("puppet_clearance_m = 0.015", "puppet_clearance_m = 5")))
    with pytest.raises(RobotConfigError, match=r"^g1.toml: upper_body.puppet_clearance_m: expected a number"):
        load_config(_write(tmp_path, "g1", text.replace("puppet_clearance_m = 0.015", 'puppet_clearance_m = "wide"')))
