"""Robot config files: every shipped one loads; malformed ones fail with one precise line."""

from __future__ import annotations

from pathlib import Path

import pytest

from engine.robot.config import RobotConfigError, load_config, load_robot_config, robot_names, robots_dir

EXPECTED = {"g1", "talos", "go1", "go2", "a1", "b1", "anymal_c", "human"}


def test_library_has_the_eight_robots_default_first():
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
