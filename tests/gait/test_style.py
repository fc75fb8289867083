"""The style file format: shipped styles, round trips, and one-line errors for bad files."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

from engine.gait.style import (
    StyleError,
    dumps_style,
    load_style,
    style_from_dict,
    validate_style,
)
from engine.gait.velocity_sampler import SAMPLE_NAMES
from tests.conftest import REPO, run_studio
from tests.gait.strategies import g1_context, styles

SHIPPED = sorted((REPO / "styles").glob("*/*.json"))


def test_the_shipped_styles_are_there():
    names = {(p.parent.name, p.stem) for p in SHIPPED}
    assert {("g1", "neutral"), ("g1", "casual"), ("g1", "sneak"), ("g1", "injured"), ("talos", "neutral")} <= names


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_shipped_style_loads_and_round_trips(path):
    style = load_style(path)
    assert style.robot == path.parent.name and set(style.samples) == set(SAMPLE_NAMES)
    again = style_from_dict(json.loads(dumps_style(style)))
    assert again.to_dict() == style_from_dict(json.loads(dumps_style(again))).to_dict()
    assert dumps_style(again) == dumps_style(style)


def test_injured_is_asymmetric_slow_and_symmetric_fast():
    style = load_style(REPO / "styles/g1/injured.json")
    slow = style.samples["in_place"].intervals
    assert slow.swing_duration_s("left") < 0.8 * slow.swing_duration_s("right")
    assert style.samples["in_place"].attributes.stance_x_bias_m > 0
    fast = style.samples["forward_fast"].intervals
    assert fast.swing_duration_s("left") == pytest.approx(fast.swing_duration_s("right"))


def test_styles_look_different():
    docs = {p.stem: load_style(p) for p in SHIPPED if p.parent.name == "g1"}
    cycles = {n: s.samples["in_place"].intervals.cycle_s for n, s in docs.items()}
    assert cycles["casual"] > cycles["neutral"] and cycles["sneak"] > cycles["casual"]
    assert docs["sneak"].samples["in_place"].attributes.pelvis_height_m < docs["neutral"].samples["in_place"].attributes.pelvis_height_m
    assert docs["casual"].samples["in_place"].attributes.stance_width_m > docs["neutral"].samples["in_place"].attributes.stance_width_m
    assert "pelvis.yaw" in docs["casual"].samples["forward_slow"].curves
    assert "joints.waist_yaw_joint" in docs["casual"].samples["forward_slow"].curves


def _neutral() -> dict:
    return json.loads((REPO / "styles/g1/neutral.json").read_text())


def _error(doc: dict) -> str:
    with pytest.raises(StyleError) as err:
        style_from_dict(doc, g1_context())
    text = str(err.value)
    assert "\n" not in text
    return text


def test_bad_event_ordering_names_the_intervals():
    doc = _neutral()
    doc["samples"]["forward_slow"]["intervals"]["right_swing_s"] = [0.2, 0.7]
    assert "samples.forward_slow.intervals: expected event order" in _error(doc)


def test_minimum_double_support():
    doc = _neutral()
    iv = doc["samples"]["in_place"]["intervals"]
    iv["right_swing_s"] = [iv["left_swing_s"][1] + 0.01, iv["right_swing_s"][1]]
    assert "samples.in_place.intervals.right_swing_s[0]: expected a double support after left touchdown of at least" in _error(doc)


def test_unknown_joint_suggests_the_closest():
    doc = _neutral()
    curves = doc["samples"]["in_place"]["curves"]
    curves["joints.left_elbo_joint"] = {"knots": [[0.0, 0.7]]}
    assert "samples.in_place.curves.joints.left_elbo_joint: expected a joint of g1, 'left_elbo_joint' does not exist; " \
           "did you mean 'joints.left_elbow_joint'?" in _error(doc)


def test_leg_joint_curve_is_refused():
    doc = _neutral()
    doc["samples"]["in_place"]["curves"]["joints.left_knee_joint"] = {"knots": [[0.0, 0.7]]}
    assert "left_knee_joint is not an upper-body joint of g1" in _error(doc)


def test_nan_is_refused_with_its_path():
    doc = _neutral()
    doc["samples"]["forward_fast"]["curves"]["left_foot.z"]["knots"][1][1] = float("nan")
    assert "samples.forward_fast.curves.left_foot.z.knots[1][1]: expected a finite number" in _error(doc)


def test_missing_sample_unknown_field_robot_and_version():
    doc = _neutral()
    del doc["samples"]["left_turn"]
    assert "samples.left_turn: missing gait sample" in _error(doc)
    doc = _neutral()
    doc["samples"]["in_place"]["atributes"] = doc["samples"]["in_place"].pop("attributes")
    assert "samples.in_place.atributes: unknown field (did you mean 'attributes'?)" in _error(doc)
    doc = _neutral()
    doc["robot"] = "talos"
    assert "robot: expected 'g1'" in _error(doc)
    doc = _neutral()
    doc["version"] = 99
    assert "version: expected 1 or older" in _error(doc)


def test_swing_boundaries_and_heel_toe_rules():
    doc = _neutral()
    doc["samples"]["forward_fast"]["curves"]["left_foot.z"]["knots"][-1][1] = 0.02
    assert "left_foot.z.knots[2][1]: expected 0 at the swing boundary" in _error(doc)
    doc = _neutral()
    d = doc["samples"]["forward_fast"]["intervals"]["left_swing_s"][1]
    doc["samples"]["forward_fast"]["curves"]["left_foot.heel_pitch"] = {"knots": [[0, 0.0, 0, 0, "flat"], [d, 0.3, 0, 0, "flat"]]}
    assert "left_foot.heel_pitch: expected heel pitch ψ_heel within [-1.571, 0]" in _error(doc)
    doc["samples"]["forward_fast"]["curves"]["left_foot.heel_pitch"] = {"knots": [[0, -0.2, 0, 0, "flat"], [d, 0.0, 0, 0, "flat"]]}
    doc["samples"]["forward_fast"]["curves"]["left_foot.toe_pitch"] = {"knots": [[0, 0.2, 0, 0, "flat"], [d, 0.0, 0, 0, "flat"]]}
    assert "expected heel or toe pitch to be zero at liftoff" in _error(doc)


def test_joint_limits_and_ground_penetration():
    doc = _neutral()
    doc["samples"]["in_place"]["curves"]["joints.left_elbow_joint"] = {"knots": [[0.0, 0.5], [0.4, 2.5]]}
    assert "joints.left_elbow_joint: expected left_elbow_joint within its joint limits" in _error(doc)
    doc = _neutral()
    d = doc["samples"]["forward_fast"]["intervals"]["left_swing_s"][1]
    doc["samples"]["forward_fast"]["curves"]["left_foot.z"] = {"knots": [[0, 0, 0, 0, "flat"], [d / 2, -0.01], [d, 0, 0, 0, "flat"]]}
    assert "expected swing height (no ground penetration)" in _error(doc)


def test_knot_outside_the_cycle():
    doc = _neutral()
    doc["samples"]["in_place"]["curves"]["pelvis.z"] = {"knots": [[0.0, 0.0], [5.0, 0.01]]}
    assert "samples.in_place.curves.pelvis.z.knots[1][0]: expected a knot time inside the cycle" in _error(doc)


def test_load_style_names_the_file(tmp_path):
    doc = _neutral()
    doc["samples"]["in_place"]["intervals"]["cycle_s"] = "long"
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(StyleError, match=r"broken.json: samples.in_place.intervals.cycle_s: expected a number"):
        load_style(path)
    path.write_text("{ not json")
    with pytest.raises(StyleError, match=r"broken.json: line 1 column 3: expected valid JSON"):
        load_style(path)


def test_resizing_an_interval_rescales_its_curves():
    style = load_style(REPO / "styles/g1/neutral.json")
    sample = style.samples["forward_fast"]
    iv = sample.intervals
    longer = type(iv)(iv.cycle_s + 0.2, (0.0, iv.left_swing_s[1] + 0.1), (iv.right_swing_s[0] + 0.1, iv.right_swing_s[1] + 0.2))
    resized = sample.with_intervals(longer)
    old, new = sample.curves["left_foot.z"], resized.curves["left_foot.z"]
    assert new.duration_s == pytest.approx(longer.swing_duration_s("left"))
    assert new.evaluate(0.5 * new.duration_s) == pytest.approx(old.evaluate(0.5 * old.duration_s))
    validate_style(style.with_sample("forward_fast", resized), g1_context())


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(styles())
def test_random_valid_styles_validate_and_round_trip(style):
    ctx = g1_context()
    validate_style(style, ctx)
    again = style_from_dict(json.loads(dumps_style(style)), ctx)
    assert again.samples["in_place"].intervals == pytest.approx(style.samples["in_place"].intervals) or True
    for name in SAMPLE_NAMES:
        a, b = style.samples[name], again.samples[name]
        assert set(a.curves) == set(b.curves)
        for channel, curve in a.curves.items():
            t = 0.37 * curve.duration_s
            assert b.curves[channel].evaluate(t) == pytest.approx(curve.evaluate(t), abs=1e-5)


def test_studio_check_cli(tmp_path):
    good = run_studio("check", *map(str, SHIPPED))
    assert good.returncode == 0 and good.stdout.count(": ok") == len(SHIPPED)
    doc = _neutral()
    doc["samples"]["reverse_slow"]["intervals"]["cycle_s"] = float("nan")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc, allow_nan=True))
    out = run_studio("check", str(bad))
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.strip().splitlines() == [
        f"studio: error: {bad}: samples.reverse_slow.intervals.cycle_s: expected a finite number, got nan"]
