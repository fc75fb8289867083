"""Balance recovery: the planner blends a style toward the robot's neutral gait while ξ is off the plan (issue 13)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.control.recovery_blend import RecoveryBlend
from engine.control.walking_parameters import WalkingParameters
from engine.gait.offline_plan import planner_for
from engine.gait.planner import PlannerFeedback
from engine.gait.style import StyleContext, load_style, styles_dir
from engine.gait.style_space import random_style
from engine.robot.model import load_robot

ON = dataclasses.replace(WalkingParameters(), recovery_xi_error_m=0.03, recovery_full_xi_error_m=0.08,
                         recovery_rise_s=0.1, recovery_hold_s=1.0, recovery_decay_s=2.0, recovery_share_step=0.05)
DT = 0.008


def test_off_by_default_and_then_always_zero():
    blend = RecoveryBlend(WalkingParameters())
    assert not blend.enabled
    assert all(blend.update(e, DT) == 0.0 for e in (0.0, 0.1, 1.0, math.inf))
    assert blend.time_in_recovery_s == 0.0


def test_rises_within_the_rise_time_holds_then_decays():
    blend = RecoveryBlend(ON)
    assert blend.update(0.02, DT) == 0.0  # below the start: the style as authored
    shares = [blend.update(0.2, DT) for _ in range(int(0.1 / DT) + 2)]  # far off the plan
    assert shares[0] == pytest.approx(0.10, abs=0.026)  # 0.08 of 1 per tick, quantised to 0.05
    assert shares[-1] == 1.0 and all(b >= a for a, b in zip(shares, shares[1:]))
    held = [blend.update(0.0, DT) for _ in range(int(ON.recovery_hold_s / DT) - 1)]
    assert held == [1.0] * len(held)  # back in balance: the neutral gait holds for the hold time
    decay = [blend.update(0.0, DT) for _ in range(int((ON.recovery_decay_s + 0.2) / DT))]
    assert decay[-1] == 0.0 and all(b <= a for a, b in zip(decay, decay[1:]))
    # it took about the decay time to come back (quantisation: within one step)
    first_zero = decay.index(0.0) * DT
    assert ON.recovery_decay_s * 0.9 <= first_zero <= ON.recovery_decay_s + DT
    assert blend.time_in_recovery_s > ON.recovery_hold_s


def test_a_walk_starts_neutral_then_eases_into_the_style_and_that_is_not_a_recovery():
    """``recovery_start_neutral_s``: fully neutral from reset for that long plus the hold, then the decay hands over
    to the style; the start counts neither as recovery time nor share, and is flagged as the start."""
    params = dataclasses.replace(ON, recovery_start_neutral_s=1.5)
    blend = RecoveryBlend(params)
    blend.reset()
    assert blend.blend_share == 1.0 and blend.starting
    held = [blend.update(0.0, DT) for _ in range(int((1.5 + ON.recovery_hold_s) / DT) - 1)]
    assert all(s == 1.0 for s in held) and blend.starting
    decay = [blend.update(0.0, DT) for _ in range(int((ON.recovery_decay_s + 0.2) / DT))]
    assert all(b <= a for a, b in zip(decay, decay[1:])) and decay[-1] == 0.0
    first_zero = DT * (decay.index(0.0) + 1)
    assert ON.recovery_decay_s * 0.9 <= first_zero <= ON.recovery_decay_s + 2 * DT
    assert not blend.starting
    assert blend.time_in_recovery_s == 0.0 and blend.share_time_s == 0.0  # the start is not a recovery
    # after the start, a recovery counts as before
    while blend.update(0.2, DT) < 1.0:
        pass
    assert blend.time_in_recovery_s > 0.0 and not blend.starting


def test_an_error_that_asks_for_the_whole_share_during_the_start_makes_it_a_recovery():
    blend = RecoveryBlend(dataclasses.replace(ON, recovery_start_neutral_s=1.5))
    blend.reset()
    for _ in range(10):
        blend.update(0.0, DT)
    assert blend.starting and blend.time_in_recovery_s == 0.0
    blend.update(0.2, DT)  # ξ far off the plan: the share is now a recovery's
    assert not blend.starting and blend.time_in_recovery_s == DT
    blend.reset()  # a new walk starts neutral again
    assert blend.starting and blend.blend_share == 1.0 and blend.time_in_recovery_s == 0.0


def test_without_a_start_time_a_walk_starts_with_the_style():
    blend = RecoveryBlend(ON)
    blend.reset()
    assert blend.blend_share == 0.0 and not blend.starting
    assert blend.update(0.0, DT) == 0.0
    off = RecoveryBlend(dataclasses.replace(WalkingParameters(), recovery_start_neutral_s=1.5))  # recovery off
    off.reset()
    assert off.blend_share == 0.0 and not off.starting


def test_target_is_proportional_between_the_two_errors():
    blend = RecoveryBlend(ON)
    assert blend.target(0.03) == 0.0 and blend.target(0.08) == 1.0
    assert blend.target(0.055) == pytest.approx(0.5)
    assert blend.target(math.nan) == 1.0  # a broken estimate recovers rather than trusting the style


def test_the_step_adjustment_counts_only_when_enabled_and_the_larger_signal_wins():
    assert RecoveryBlend(ON).target(0.0, 0.5) == 0.0  # recovery_step_adjust_m is off (inf) by default
    both = dataclasses.replace(ON, recovery_step_adjust_m=0.1, recovery_full_step_adjust_m=0.3)
    blend = RecoveryBlend(both)
    assert blend.target(0.0, 0.1) == 0.0 and blend.target(0.0, 0.3) == 1.0
    assert blend.target(0.0, 0.2) == pytest.approx(0.5)
    assert blend.target(0.055, 0.15) == pytest.approx(0.5)  # ξ asks 0.5, the step adjustment 0.25
    assert blend.target(0.04, 0.25) == pytest.approx(0.75)  # ξ asks 0.2, the step adjustment 0.75
    assert blend.target(0.0, math.inf) == 1.0
    assert RecoveryBlend(ON).target(0.0, math.nan) == 0.0  # off: not even a broken reading counts
    alone = RecoveryBlend(dataclasses.replace(WalkingParameters(), recovery_step_adjust_m=0.1))
    assert alone.enabled and alone.target(math.inf, 0.0) == 0.0  # the step adjustment alone switches recovery on
    shares = [blend.update(0.0, DT, 0.35) for _ in range(int(0.1 / DT) + 2)]  # footholds far from the style's
    assert shares[-1] == 1.0


def test_the_body_outside_its_double_support_counts_only_when_enabled_and_the_largest_signal_wins():
    assert RecoveryBlend(ON).target(0.0, 0.0, 0.5) == 0.0  # recovery_support_outside_m is off (inf) by default
    alone = RecoveryBlend(dataclasses.replace(WalkingParameters(), recovery_support_outside_m=0.02,
                                              recovery_full_support_outside_m=0.05))
    assert alone.enabled  # the support signal alone switches recovery on
    assert alone.target(0.0, 0.0, 0.02) == 0.0 and alone.target(0.0, 0.0, 0.05) == 1.0
    assert alone.target(0.0, 0.0, 0.035) == pytest.approx(0.5)
    assert alone.target(0.0, 0.0, math.nan) == 1.0  # on: a broken reading recovers
    three = RecoveryBlend(dataclasses.replace(ON, recovery_step_adjust_m=0.1, recovery_full_step_adjust_m=0.3,
                                              recovery_support_outside_m=0.02, recovery_full_support_outside_m=0.05))
    assert three.target(0.055, 0.15, 0.026) == pytest.approx(0.5)  # ξ asks 0.5, the others 0.25 and 0.2
    assert three.target(0.04, 0.15, 0.0425) == pytest.approx(0.75)  # the support asks 0.75
    # In a walk it counts once the CoM has stayed beyond the start for recovery_support_outside_for_s (0.1 s):
    # a touchdown passing through a thin support for a few ticks asks for nothing.
    for_ticks = math.ceil(three.params.recovery_support_outside_for_s / DT - 1e-9)
    assert [three.update(0.0, DT, 0.0, 0.06) for _ in range(for_ticks - 1)] == [0.0] * (for_ticks - 1)
    assert three.update(0.0, DT, 0.0, 0.01) == 0.0  # back inside: the count starts again
    assert [three.update(0.0, DT, 0.0, 0.06) for _ in range(for_ticks - 1)] == [0.0] * (for_ticks - 1)
    shares = [three.update(0.0, DT, 0.0, 0.06) for _ in range(int(0.1 / DT) + 2)]  # the body stays behind both toes
    assert shares[0] > 0.0 and shares[-1] == 1.0
    three.idle()
    assert three.update(0.0, DT, 0.0, 0.06) == 0.0  # a new count after the recovery was idled


def test_the_controller_measures_the_body_outside_the_references_double_support_only():
    """``WalkingController._outside_support_m``: 0 with the CoM between the feet, the distance past the toes with it
    ahead of them, 0 in single support and where the robot does not count it."""
    from engine.control.walking_controller import WalkingController
    from engine.sim import Simulation

    robot = load_robot("g1")
    neutral = load_style(styles_dir("g1") / "neutral.json", StyleContext.for_robot("g1"))
    controller = WalkingController(robot, neutral)
    assert math.isfinite(controller.params.recovery_support_outside_m)  # on for G1 (robots/g1.toml)
    sim = Simulation(robot, controller)
    sim.reset()
    for _ in range(8):  # two planner ticks: a reference standing on both flat feet
        controller.set_command(np.zeros(3))
        sim.step()
    ref = controller.ref
    assert ref is not None and ref.contact.all() and ref.corner_contact.all()
    corners = ref.sole_corners[:, :, :2].reshape(-1, 2)
    middle = corners.mean(axis=0)
    assert controller._outside_support_m(middle) == 0.0
    toe_x = float(corners[:, 0].max())
    ahead = np.array([toe_x + 0.07, middle[1]])
    assert controller._outside_support_m(ahead) == pytest.approx(0.07, abs=1e-3)  # the feet point along x standing
    ref.contact = np.array([True, False])
    assert controller._outside_support_m(ahead) == 0.0  # single support: the CoM is outside the foot by design
    ref.contact = np.array([True, True])
    controller.params = dataclasses.replace(controller.params, recovery_support_outside_m=math.inf)
    assert controller._outside_support_m(ahead) == 0.0


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 0.3), min_size=1, max_size=400))
def test_share_stays_in_range_and_on_the_grid(errors):
    blend = RecoveryBlend(ON)
    for e in errors:
        s = blend.update(e, DT)
        assert 0.0 <= s <= 1.0
        assert abs(s / ON.recovery_share_step - round(s / ON.recovery_share_step)) < 1e-9


@pytest.fixture(scope="module")
def g1_styles():
    robot = load_robot("g1")
    ctx = StyleContext.for_robot("g1")
    neutral = load_style(styles_dir("g1") / "neutral.json", ctx)
    style = random_style(np.random.default_rng(3), ctx, neutral, 0.3, name="random-test")
    return robot, ctx, neutral, style


@pytest.mark.parametrize("share", [0.0, 0.35, 1.0])
def test_planner_blends_the_neutral_gait_by_its_share(g1_styles, share):
    """The blend's attributes (pelvis height, stance width, timings …) are the style's and the neutral gait's
    mixed by the share, at every command; share 0 is the style exactly."""
    robot, ctx, neutral, style = g1_styles
    plain = planner_for(robot, style, ctx)
    mixed = planner_for(robot, style, ctx)
    only_neutral = planner_for(robot, neutral, ctx)
    mixed.set_recovery_style(neutral)
    command = np.array([0.5 * style.velocities.x_max_mps, 0.0, 0.0])
    for _ in range(3):
        plain.step(DT, command)
        mixed.step(DT, command, PlannerFeedback(recovery_share=share))
    weights = plain.weights
    # the neutral gait at the style's sample weights (the style's velocities pick the samples)
    only_neutral._weight_list = list(weights)
    neutral_blend = only_neutral.banks.blend([(w, only_neutral.banks.banks[n]) for w, n in
                                              zip(weights, plain.banks.banks) if w > 1e-9])
    for name in ("pelvis_height_m", "stance_width_m"):
        want = (1 - share) * plain.blend.attribute(name) + share * neutral_blend.attribute(name)
        assert mixed.blend.attribute(name) == pytest.approx(want, abs=1e-12)
    np.testing.assert_allclose(mixed.blend.events_array,
                               (1 - share) * plain.blend.events_array + share * neutral_blend.events_array, atol=1e-12)
    if share == 0.0:
        assert mixed.blend.attribute("pelvis_height_m") == plain.blend.attribute("pelvis_height_m")


def test_a_share_change_keeps_the_reference_continuous(g1_styles):
    """Going from the style to the neutral gait in the controller's steps moves the feet and pelvis a little per
    planner tick (a blend in phase space, like the sample blending), never a jump."""
    robot, ctx, neutral, style = g1_styles
    planner = planner_for(robot, style, ctx)
    planner.set_recovery_style(neutral)
    command = np.array([0.5 * style.velocities.x_max_mps, 0.0, 0.0])
    blend = RecoveryBlend(ON)
    prev = None
    jumps = []
    for k in range(int(4.0 / DT)):
        error = 0.2 if 1.0 <= k * DT < 1.3 else 0.0  # a 0.3 s disturbance
        ref = planner.step(DT, command, PlannerFeedback(recovery_share=blend.update(error, DT)))
        if prev is not None:
            jumps.append(max(abs(ref.pelvis_z - prev[0]), float(np.abs(ref.foot_pos - prev[1]).max())))
        prev = (ref.pelvis_z, ref.foot_pos.copy())
    assert blend.time_in_recovery_s > 1.0
    assert max(jumps) < 0.02  # m per 8 ms tick (a swing foot moves ≈ 1 m/s at most: 8 mm)


def test_the_neutral_style_recovering_toward_itself_is_bit_identical(g1_styles):
    """Walking the neutral style, a recovery share changes nothing, bit for bit (the shipped neutral walk and
    the push benchmark keep their numbers); an edit away from it brings the recovery blend back."""
    robot, ctx, neutral, style = g1_styles
    plain = planner_for(robot, neutral, ctx)
    mixed = planner_for(robot, neutral, ctx)
    mixed.set_recovery_style(load_style(styles_dir("g1") / "neutral.json", ctx))
    command = np.array([0.3, 0.05, 0.1])
    for k in range(200):
        a = plain.step(DT, command)
        b = mixed.step(DT, command, PlannerFeedback(recovery_share=0.5 if k % 50 > 20 else 0.0))
        assert a.pelvis_z == b.pelvis_z and np.array_equal(a.foot_pos, b.foot_pos)
    assert not mixed.recovers_toward_other_gait  # (the controller then reports no recovery either)
    mixed.set_style(style)
    assert mixed.recovers_toward_other_gait
    mixed.step(DT, command, PlannerFeedback(recovery_share=0.5))
    neutral_banks = set(map(id, mixed.recovery_banks.banks.values()))
    assert any(id(b) in neutral_banks for _, b in mixed.blend.members)  # the edited style blends toward neutral


def test_a_push_sends_a_styled_walk_toward_neutral_and_the_neutral_walk_reports_nothing(g1_styles):
    """Closed loop (G1, recovery on in robots/g1.toml): a 1.5 N/kg side push while walking in place drives ξ off
    the plan; a random style then walks part neutral for a while and the walk's summary says so, the neutral style
    (nothing to blend toward) reports no recovery, and neither falls."""
    from engine.gait.command_schedule import parse_command
    from engine.walk_runner import PushSpec, run_walk

    robot, ctx, neutral, style = g1_styles
    assert WalkingParameters.for_robot("g1").recovery_xi_error_m < 0.1  # on for G1
    push = [PushSpec(2.0, (0.0, 1.5 * robot.mass_kg, 0.0), 1.0)]
    styled, _ = run_walk(robot, style, parse_command("0,0,0", style.velocities), 5.0, push)
    plain, _ = run_walk(robot, neutral, parse_command("0,0,0", neutral.velocities), 5.0, push)
    assert not styled["fell"] and not plain["fell"]
    assert styled["recovery_time_s"] > 0.3 and 0.0 < styled["recovery_mean_share"] <= 1.0
    assert plain["recovery_time_s"] == 0.0 and plain["recovery_mean_share"] == 0.0


def test_talos_starts_a_styled_walk_in_its_neutral_gait_and_hands_over_to_the_style():
    """Closed loop (TALOS sets recovery_start_neutral_s in robots/talos.toml, G1 does not): the planner blends all
    neutral from the first tick, the telemetry marks it as the start, and the style is fully in after
    start + hold + decay (3.5 s); G1's controller starts with the style."""
    from engine.control.walking_controller import WalkingController
    from engine.sim import Simulation

    robot = load_robot("talos")
    ctx = StyleContext.for_robot("talos")
    neutral = load_style(styles_dir("talos") / "neutral.json", ctx)
    style = random_style(np.random.default_rng(3), ctx, neutral, 0.2, name="random-test")
    params = WalkingParameters.for_robot("talos")
    assert params.recovery_start_neutral_s > 0.0 and WalkingParameters.for_robot("g1").recovery_start_neutral_s == 0.0
    controller = WalkingController(robot, style)
    sim = Simulation(robot, controller)
    sim.reset()
    dt = float(robot.mj_model.opt.timestep)
    seen: list[tuple[float, float, bool]] = []
    end_s = params.recovery_start_neutral_s + params.recovery_hold_s + params.recovery_decay_s + 0.5
    for k in range(int(end_s / dt)):
        controller.set_command(np.zeros(3))
        sim.step()
        if k % 25 == 0:
            tel = controller.telemetry
            seen.append((k * dt, tel.recovery_share, tel.recovery_starting))
    assert not sim.fallen
    early = [s for t, s, _ in seen if t < params.recovery_start_neutral_s]
    assert early and all(s == 1.0 for s in early) and all(flag for t, _, flag in seen if t < params.recovery_start_neutral_s)
    assert seen[-1][1] == 0.0 and not seen[-1][2]  # the style as authored, and not "starting" any more
    assert controller.recovery.time_in_recovery_s == 0.0  # standing in place: no recovery, the start not counted
    g1 = WalkingController(load_robot("g1"), random_style(np.random.default_rng(3), StyleContext.for_robot("g1"),
                                                          load_style(styles_dir("g1") / "neutral.json"), 0.2))
    g1_sim = Simulation(g1.robot, g1)
    g1_sim.reset()
    g1_sim.step()
    assert g1.planner.recovery_share == 0.0 and not g1.recovery.starting
