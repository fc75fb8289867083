"""The edit-time feasibility check: the shipped styles pass, constructed impossible ones are
flagged with the sample, the phase and what to do."""

from __future__ import annotations

import dataclasses

import pytest

from engine.gait.feasibility import check_style
from engine.gait.style import StyleContext, load_style, validate_style
from engine.robot.model import load_robot
from tests.conftest import REPO

SHIPPED = [("g1", "neutral"), ("g1", "casual"), ("g1", "sneak"), ("g1", "injured"), ("talos", "neutral")]


@pytest.mark.parametrize(("robot", "name"), SHIPPED, ids=lambda x: x)
def test_shipped_styles_pass_the_check(robot, name):
    style = load_style(REPO / "styles" / robot / f"{name}.json")
    assert check_style(load_robot(robot), style) == []


def _neutral(robot="g1"):
    ctx = StyleContext.for_robot(robot)
    return ctx, load_style(REPO / "styles" / robot / "neutral.json", ctx)


def _every_sample(style, fn):
    return dataclasses.replace(style, samples={k: fn(v) for k, v in style.samples.items()})


def test_a_stride_longer_than_the_legs_is_flagged():
    ctx, neutral = _neutral()
    style = dataclasses.replace(neutral, velocities=dataclasses.replace(neutral.velocities, x_max_mps=1.5))
    validate_style(style, ctx)  # the validator lets it through ...
    findings = check_style(load_robot("g1"), style, samples=("forward_fast",))
    assert findings and findings[0].sample == "forward_fast"  # ... the check does not
    assert any(f.kind == "reach" and "shorten the stride" in f.message for f in findings)
    assert all(0.0 <= f.phase_pct <= 100.0 for f in findings)


def test_a_pelvis_too_high_for_the_knees_is_flagged():
    ctx, neutral = _neutral()
    top = ctx.pelvis_height_range_m[1]
    style = _every_sample(neutral, lambda s: dataclasses.replace(
        s, attributes=dataclasses.replace(s.attributes, pelvis_height_m=top)))
    validate_style(style, ctx)
    findings = check_style(load_robot("g1"), style, samples=("forward_fast",))
    assert any(f.kind == "joint_limit" and "knee straight" in f.message and "lower the pelvis" in f.message
               for f in findings), [f.text() for f in findings]


def test_a_foot_that_never_lifts_is_flagged():
    ctx, neutral = _neutral()
    sample = neutral.samples["in_place"]
    curves = {k: v for k, v in sample.curves.items() if not k.endswith("_foot.z")}
    style = neutral.with_sample("in_place", dataclasses.replace(sample, curves=curves))
    validate_style(style, ctx)
    findings = check_style(load_robot("g1"), style, samples=("in_place",))
    assert {f.side for f in findings if f.kind == "clearance"} == {"left", "right"}
    assert "raise its swing height" in findings[0].message or any("raise its swing height" in f.message for f in findings)
