"""Robot-level physical bounds of the style validator (engine/gait/leg_reach.py, issue 13): a swing foot's
roll within the ankle roll joint's range, and each sample's steps (its velocity × its timings) within what
two legs reach at its pelvis height. A style just past a bound is refused with the field path; the
shipped styles pass."""

from __future__ import annotations

import json
from functools import lru_cache

import pytest

from engine.gait.leg_reach import max_reachable_speed, sample_step_reach
from engine.gait.style import StyleContext, StyleError, style_from_dict
from tests.conftest import REPO

SHIPPED = sorted((REPO / "styles").glob("*/*.json"))


@lru_cache(maxsize=None)
def context(robot: str) -> StyleContext:
    return StyleContext.for_robot(robot)


def _doc(robot: str) -> dict:
    return json.loads((REPO / f"styles/{robot}/neutral.json").read_text())


def _error(doc: dict, robot: str) -> str:
    with pytest.raises(StyleError) as err:
        style_from_dict(doc, context(robot))
    text = str(err.value)
    assert "\n" not in text
    return text


def test_the_reach_comes_from_the_robot_model():
    g1, talos = context("g1").leg_reach, context("talos").leg_reach
    assert g1 is not None and talos is not None
    assert g1.ankle_roll_range_rad == pytest.approx(0.2618, abs=1e-4)  # G1's ankle roll joint: ±0.2618 rad
    assert talos.ankle_roll_range_rad == pytest.approx(0.5236, abs=1e-4)  # TALOS leg_*_6: ±0.5236 rad
    # The leg's links summed, hip joint to ankle joint: G1's straight leg (0.639 m hip pitch to ankle) is kinked
    # by the hip's offsets (0.698 m summed); TALOS's leg is straight (0.38 + 0.325 m).
    assert g1.leg_length_m == pytest.approx(0.698, abs=1e-3)
    assert talos.leg_length_m == pytest.approx(0.705, abs=1e-3)
    assert g1.ankle_height_m == pytest.approx(0.035, abs=1e-3) and talos.ankle_height_m == pytest.approx(0.107, abs=1e-3)


@pytest.mark.parametrize("robot, roll", [("g1", 0.2618), ("talos", 0.5236)])
def test_a_swing_roll_past_the_ankle_is_refused(robot, roll):
    doc = _doc(robot)
    d = doc["samples"]["forward_slow"]["intervals"]["left_swing_s"][1]

    def with_roll(value: float) -> dict:
        out = json.loads(json.dumps(doc))
        out["samples"]["forward_slow"]["curves"]["left_foot.roll"] = {
            "knots": [[0, 0, 0, 0, "flat"], [d / 2, value, 0, 0, "flat"], [d, 0, 0, 0, "flat"]]}
        return out

    style_from_dict(with_roll(-(roll - 0.005)), context(robot))  # inside: fine
    text = _error(with_roll(-(roll + 0.005)), robot)
    assert f"samples.forward_slow.curves.left_foot.roll: expected a foot roll the ankle roll joint reaches (±{roll:.4g} rad) " \
           f"within [{-roll:.4g}, {roll:.4g}], the curve reaches {-(roll + 0.005):.4g}" in text


@pytest.mark.parametrize("robot, field, sample", [("g1", "x_max_mps", "forward_fast"), ("g1", "x_slow_mps", "reverse_slow"),
                                                  ("talos", "x_max_mps", "reverse_fast"), ("g1", "y_max_mps", "left_strafe")])
def test_a_step_past_the_legs_reach_is_refused(robot, field, sample):
    """A sample stretched to the longest cycle the validator allows steps (velocity × the time between two
    contacts' middles) past the legs' reach a little above its neutral velocity: just below that velocity the
    style validates, just above it the velocity field is refused, naming the sample and the distances."""
    ctx = context(robot)
    doc = _doc(robot)
    raw = doc["samples"][sample]
    scale = (ctx.max_cycle_s - 1e-6) / raw["intervals"]["cycle_s"]
    iv = raw["intervals"]
    iv["cycle_s"] *= scale
    iv["left_swing_s"] = [t * scale for t in iv["left_swing_s"]]
    iv["right_swing_s"] = [t * scale for t in iv["right_swing_s"]]
    for curve in raw.get("curves", {}).values():  # (curves follow in time: knots later, slopes flatter)
        curve["knots"] = [[k[0] * scale, k[1], k[2] / scale, k[3] / scale, k[4]] if len(k) == 5 else [k[0] * scale, *k[1:]]
                          for k in curve["knots"]]
    base = style_from_dict(doc, None)
    unit = tuple(1.0 if v > 0 else (-1.0 if v < 0 else 0.0) for v in base.velocities.velocity_of(sample))
    top = max_reachable_speed(ctx.leg_reach, base.samples[sample], unit)
    assert 0.05 < top < 1.5
    style_from_dict(_with(doc, field, 0.99 * top), ctx)
    text = _error(_with(doc, field, 1.02 * top), robot)
    assert text.startswith(f"style: velocities.{field}: expected at most ") or f"velocities.{field}: expected at most " in text
    assert f"(or a shorter samples.{sample}.intervals.cycle_s or a lower pelvis)" in text
    assert "more than the legs reach at its pelvis height" in text
    past = style_from_dict(_with(doc, field, 1.02 * top), None)  # (no robot context: no reach bound)
    found = sample_step_reach(ctx.leg_reach, past.samples[sample], past.velocities.velocity_of(sample))
    assert found.ankle_distance_m > found.limit_m


def _with(doc: dict, field: str, value: float) -> dict:
    """``doc`` with velocity ``field`` at ``value`` (x_max above x_slow kept)."""
    out = json.loads(json.dumps(doc))
    v = out["velocities"]
    v[field] = value
    if field == "x_max_mps":
        v["x_slow_mps"] = min(v["x_slow_mps"], 0.5 * value)
    if field == "x_slow_mps":
        v["x_max_mps"] = max(v["x_max_mps"], 1.01 * value)
    return out


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_the_shipped_styles_step_well_within_reach(path):
    robot = path.parent.name
    if robot not in ("g1", "talos"):
        pytest.skip("issue 13 bounds G1 and TALOS (the dino is a test robot)")
    ctx = context(robot)
    style = style_from_dict(json.loads(path.read_text()), ctx)
    for name, sample in style.samples.items():
        found = sample_step_reach(ctx.leg_reach, sample, style.velocities.velocity_of(name))
        assert found.ankle_distance_m < 0.5 * found.limit_m, name  # shipped steps: at most half the reach
