"""Rehearsal (engine/gait/rehearsal.py): the sweep walked in physics, its verdict in an animator's words."""

from __future__ import annotations

import shutil
import subprocess
import sys
import time

import numpy as np
import pytest

from engine.gait.rehearsal import DRIFT_M, EDGES_S, SLIDE_M, combine, describe, rehearse
from engine.gait.velocity_sampler import SAMPLE_NAMES
from tests.conftest import REPO


def _recording(n: int = 200, dt: float = 0.008, drift_from: int | None = None, drift_dir=(-1.0, 0.0),
               slide_from: int | None = None, yaw: float = 0.0) -> dict[str, np.ndarray]:
    """A walk's analysis arrays: the body on its plan, both feet on the ground where they landed; optionally the
    body leaving the plan along ``drift_dir`` (in the heading frame) or the left foot sliding from a frame on."""
    t = np.arange(n) * dt
    com_ref = np.stack([0.3 * t, np.zeros(n)], axis=1)
    com = np.concatenate([com_ref, np.full((n, 1), 0.7)], axis=1)
    c, s = np.cos(yaw), np.sin(yaw)
    if drift_from is not None:
        grow = np.clip((np.arange(n) - drift_from) * 0.002, 0.0, None)[:, None]
        d = np.array(drift_dir)
        com[:, :2] += grow * np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])
    feet = np.zeros((n, 2, 3))
    feet[:, 1, 1] = -0.2
    stance_drift = np.zeros((n, 2))  # what the stance slip meter records: the sole's drift since its stance began
    if slide_from is not None:
        feet[slide_from:, 0, 0] = np.arange(n - slide_from) * 0.001
        stance_drift[slide_from:, 0] = np.arange(n - slide_from) * 0.001
    weights = np.zeros((n, len(SAMPLE_NAMES)))
    weights[:, SAMPLE_NAMES.index("forward_fast")] = 0.8
    weights[:, SAMPLE_NAMES.index("in_place")] = 0.2
    return {"t": t, "com": com, "com_ref": com_ref, "pelvis_yaw_achieved": np.full(n, yaw),
            "contact": np.ones((n, 2), bool), "foot_pos": feet, "stance_drift_m": stance_drift, "sample_weights": weights,
            "gait_phase": 7.0 + np.linspace(0.0, 0.4, n), "command": np.tile([0.4, 0.0, 0.0], (n, 1))}


def _summary(fell: bool, t_end: float, slip_mm: float = 0.5, cop: float = 1.0) -> dict:
    return {"fell": fell, "fall_time_s": t_end if fell else None, "max_stance_slip_mm": slip_mm,
            "cop_inside_fraction": cop}


def test_a_clean_walk_says_so_and_an_unclean_one_names_what_is_wrong():
    rec = _recording()
    clean = describe(_summary(False, 1.6), rec, 60.0)
    assert clean.clean and not clean.fell and "cleanly" in clean.message
    sliding = describe(_summary(False, 1.6, slip_mm=4.2, cop=0.98), rec, 60.0)
    assert not sliding.clean and not sliding.fell
    assert "slides up to 4.2 mm" in sliding.message and "2.0 %" in sliding.message
    assert "neutral" not in clean.message
    recovered = describe({**_summary(False, 1.6), "recovery_time_s": 12.5, "recovery_mean_share": 0.083}, rec, 60.0)
    assert "fell back toward the neutral gait for 12.5 s (8 % neutral on average)" in recovered.message


@pytest.mark.parametrize(("command", "direction", "words", "kind"), [
    ((0.4, 0.0, 0.0), (-1.0, 0.0), "fell 3 cm behind its plan along the walk", "behind"),
    ((0.4, 0.0, 0.0), (1.0, 0.0), "ran 3 cm ahead of its plan along the walk", "ahead"),
    ((-0.3, 0.0, 0.0), (-1.0, 0.0), "ran 3 cm ahead of its plan along the walk", "ahead"),  # walking backward
    ((0.0, 0.2, 0.0), (0.0, -1.0), "fell 3 cm behind its plan along the walk", "behind"),  # strafing left
    ((0.4, 0.0, 0.0), (0.0, 1.0), "drifted 3 cm sideways off its path", "across"),
    ((0.0, 0.0, 0.5), (-1.0, 0.0), "drifted 3 cm behind where it should stand", "front-back"),  # turning on the spot
    ((0.0, 0.0, 0.0), (0.0, -1.0), "drifted 3 cm right of where it should stand", "sideways"),
])
@pytest.mark.parametrize("yaw", [0.0, 2.0])
def test_a_fall_names_the_sample_phase_and_how_the_body_left_its_plan(command, direction, words, kind, yaw):
    rec = _recording(drift_from=120, drift_dir=direction, yaw=yaw)
    rec["command"] = np.tile(command, (len(rec["t"]), 1))
    result = describe(_summary(True, float(rec["t"][-1])), rec, 60.0)
    assert result.fell and result.sample == "forward_fast" and result.command == command
    assert result.phase_pct == pytest.approx(40.0, abs=0.5)
    # the drift grows 2 mm a frame from frame 120: it reaches DRIFT_M at frame 120 + 15
    assert result.onset_time_s == pytest.approx(rec["t"][120 + int(round(DRIFT_M / 0.002))], abs=0.009)
    assert words in result.message and result.onset_kind == kind
    assert "forward_fast" in result.message and "40 % of its cycle" in result.message


def test_a_foot_that_slides_before_the_body_drifts_is_named_first():
    rec = _recording(drift_from=150, slide_from=100)
    result = describe(_summary(True, float(rec["t"][-1])), rec, 60.0)
    # the left foot moves 1 mm a frame from frame 100: SLIDE_M away at frame 100 + 10
    assert result.onset_time_s == pytest.approx(rec["t"][100 + int(round(SLIDE_M / 0.001))], abs=0.009)
    assert "left foot started sliding" in result.message and result.onset_kind == "slide"


def test_a_foot_rolling_to_lift_off_is_not_sliding():
    """The plan's contact still holds a foot that rolls onto its toe (its sole centre travels a centimetre or more
    without sliding); only a sole in stance (flat in the plan, carried by the floor) counts, as the slip meter's."""
    rec = _recording(drift_from=150)
    rec["foot_pos"][100:, 0, 0] = np.arange(100) * 0.001  # the sole centre moves 10 cm: a toe-off, not in stance
    result = describe(_summary(True, float(rec["t"][-1])), rec, 60.0)
    assert result.onset_kind == "behind" and "sliding" not in result.message


def _on_toes(rec: dict[str, np.ndarray], frames: slice, outside_m: float = 0.05) -> None:
    """Both feet on their toes over ``frames`` with the body ``outside_m`` behind the toe edges."""
    n = len(rec["t"])
    rec.setdefault("support_edge", np.zeros((n, 2), dtype=np.int64))
    rec.setdefault("com_outside_support_m", np.full(n, -0.05))
    rec["support_edge"][frames] = 2
    rec["com_outside_support_m"][frames] = outside_m


def test_both_feet_on_their_toes_with_the_body_behind_them_is_named_before_the_drift_it_causes():
    """stumbly (reachable-0-17) stood 0.33 s on both toes, its body behind them, before it fell backward: the onset is
    that stance, said with what to change."""
    rec = _recording(drift_from=150)
    _on_toes(rec, slice(100, 140))  # 0.32 s
    result = describe(_summary(True, float(rec["t"][-1])), rec, 60.0)
    assert result.onset_kind == "edges" and result.onset_time_s == pytest.approx(rec["t"][100])
    assert "both feet stood on their toes with the body 3 cm outside them" in result.message
    assert "less heel or toe pitch at touchdown and liftoff" in result.message


@pytest.mark.parametrize(("frames", "outside_m", "contact_right"), [
    (slice(100, 100 + int(EDGES_S / 0.008) - 2), 0.05, True),  # walkers pass through it briefly
    (slice(100, 140), DRIFT_M - 0.005, True),  # the body not far enough outside
    (slice(100, 140), 0.05, False),  # one foot in the air: a single support on the toe is walking
])
def test_a_brief_or_near_or_single_support_on_the_edges_is_no_onset(frames, outside_m, contact_right):
    rec = _recording(drift_from=150)
    _on_toes(rec, frames, outside_m)
    rec["contact"][frames, 1] = contact_right
    result = describe(_summary(True, float(rec["t"][-1])), rec, 60.0)
    assert result.onset_kind == "behind"


def test_a_fall_without_a_visible_beginning_still_gives_sample_and_phase():
    rec = _recording()
    result = describe(_summary(True, float(rec["t"][-1])), rec, 60.0)
    assert result.fell and result.onset_time_s is None and result.onset_kind is None and "it began" not in result.message
    assert result.sample == "forward_fast" and "0.40 m/s forward" in result.message


@pytest.mark.slow
def test_rehearsing_neutral_walks_and_reports_progress():
    from engine.gait.style import StyleContext, load_style
    from engine.robot.model import load_robot

    robot = load_robot("g1")
    style = load_style(REPO / "styles/g1/neutral.json", StyleContext.for_robot("g1"))
    seen: list[float] = []
    result = rehearse(robot, style, 3.0, progress=seen.append)
    assert not result.fell and result.duration_s == 3.0
    assert seen == sorted(seen) and len(seen) == 6 and seen[0] == 0.0  # every 0.5 s of the 3 s
    assert result.max_stance_slip_mm >= 0.0 and "walks the 3 s sweep" in result.message


def test_several_walks_count_their_falls_and_tell_the_first():
    from dataclasses import replace

    rec = _recording()
    walk = describe(_summary(False, 1.6), rec, 60.0)
    fall = describe(_summary(True, 1.6), rec, 60.0)
    late = replace(fall, fall_time_s=30.0)
    assert combine([walk]) == walk and combine([fall]).falls == 1
    one = combine([walk, late, fall])
    assert one.fell and one.walks == 3 and one.falls == 2 and one.fall_time_s == 30.0  # the first fall in walk order
    assert one.message.startswith("falls in 2 of 3 walks") and late.message in one.message
    none = combine([walk, walk, walk])
    assert not none.fell and none.falls == 0 and none.message.startswith(walk.message) and "worst of 3 walks" in none.message
    # None fell: the verdict is the worst walk's figures, though they come from different walks.
    clean = replace(walk, max_stance_slip_mm=0.8, cop_inside_fraction=0.999)
    slid = replace(walk, max_stance_slip_mm=3.4, cop_inside_fraction=0.998)
    rolled = replace(walk, max_stance_slip_mm=1.0, cop_inside_fraction=0.99, recovery_time_s=2.5,
                     recovery_mean_share=0.2)
    assert combine([clean, clean]).clean and "cleanly" in combine([clean, clean]).message
    worst = combine([clean, slid, rolled])
    assert not worst.clean and worst.max_stance_slip_mm == 3.4 and worst.cop_inside_fraction == 0.99
    assert "slides up to 3.4 mm" in worst.message and "edges 1.0 %" in worst.message
    assert "for 2.5 s (20 % neutral" in worst.message and worst.message.startswith("walks the 60 s sweep")


def test_rehearsing_two_walks_nudges_the_second_and_counts_progress_over_both():
    from engine.gait.style import StyleContext, load_style
    from engine.robot.model import load_robot

    style = load_style(REPO / "styles/g1/neutral.json", StyleContext.for_robot("g1"))
    seen: list[float] = []
    verdicts = []
    result = rehearse(load_robot("g1"), style, 1.5, progress=seen.append, walks=2, on_walk=verdicts.append)
    assert seen == sorted(seen) and seen[0] == 0.0 and 1.5 <= seen[-1] < 3.0  # the second walk counts on from 1.5 s
    assert len(verdicts) == 1 and verdicts[0].walks == 1  # after the first walk only
    assert result.walks == 2 and result.falls == 0 and "worst of 2 walks" in result.message
    with pytest.raises(ValueError, match="walks"):
        rehearse(load_robot("g1"), style, 1.5, walks=0)


def test_a_raising_progress_callback_stops_the_rehearsal():
    from engine.gait.style import StyleContext, load_style
    from engine.robot.model import load_robot

    class Stop(Exception):
        pass

    def stop_at_one_second(t_s: float) -> None:
        if t_s >= 1.0:
            raise Stop

    style = load_style(REPO / "styles/g1/neutral.json", StyleContext.for_robot("g1"))
    with pytest.raises(Stop):
        rehearse(load_robot("g1"), style, 30.0, progress=stop_at_one_second)


@pytest.mark.slow
def test_the_rehearsal_command_refuses_bad_input_in_one_line(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"robot": "g1", "samples": 3}')
    for args, needle in (([ "--style", str(bad)], "bad.json"),
                         (["--style", str(tmp_path / "missing.json")], "missing.json"),
                         (["--style", str(REPO / "styles/g1/neutral.json"), "--duration", "-1"], "--duration"),
                         (["--style", str(REPO / "styles/g1/neutral.json"), "--nice", "40"], "--nice"),
                         (["--style", str(REPO / "styles/g1/neutral.json"), "--walks", "0"], "--walks")):
        out = subprocess.run([sys.executable, "-m", "engine.gait.rehearsal", "--robot", "g1", *args],
                             capture_output=True, text=True, cwd=REPO, timeout=300)
        assert out.returncode == 2, out.stderr
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0] and "Traceback" not in out.stderr


@pytest.mark.slow
def test_the_panel_runs_a_rehearsal_shows_its_verdict_and_marks_it_stale_after_an_edit(tmp_path):
    import viser

    from studio.panels.rehearsal_panel import CANCEL_LABEL, START_LABEL, RehearsalPanel
    from studio.style_session import StyleSession
    from tests.conftest import free_port

    folder = tmp_path / "g1"
    folder.mkdir()
    shutil.copy(REPO / "styles/g1/neutral.json", folder / "neutral.json")
    session = StyleSession("g1", folder=folder)
    assert session.open("neutral").ok
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        panel = RehearsalPanel(server, session, duration_s=2.0)
        panel.start()
        assert panel.button.label == CANCEL_LABEL
        deadline = time.monotonic() + 240
        while panel.running and time.monotonic() < deadline:
            time.sleep(0.2)
        for _ in range(50):  # the follower thread writes the verdict after the process ends
            if "Rehearsal:" in panel.status.content:
                break
            time.sleep(0.1)
        assert "✓ Rehearsal: walks the 2 s sweep" in panel.status.content or "⚠️ Rehearsal: walks" in panel.status.content
        assert "before your last edit" not in panel.status.content and panel.button.label == START_LABEL
        # cancel: the process ends, nothing is shown as a verdict
        panel.start()
        panel.cancel()
        for _ in range(100):
            if "cancelled" in panel.status.content:
                break
            time.sleep(0.1)
        assert "rehearsal cancelled" in panel.status.content and not panel.running
        # an edit while a rehearsal runs: its verdict is marked stale
        panel.start()
        from dataclasses import replace

        style = session.style
        sample = style.samples["in_place"]
        lower = replace(sample, attributes=replace(sample.attributes, pelvis_height_m=sample.attributes.pelvis_height_m - 0.01))
        assert session.apply(replace(style, samples={**style.samples, "in_place": lower}), "lower the pelvis").ok
        deadline = time.monotonic() + 240
        while "Rehearsal:" not in panel.status.content and time.monotonic() < deadline:
            time.sleep(0.2)
        assert "before your last edit" in panel.status.content
    finally:
        server.stop()


def test_the_verdict_markdown_marks_clean_unclean_and_falls():
    from studio.panels.rehearsal_panel import rehearsal_markdown

    assert rehearsal_markdown({"clean": True, "fell": False, "message": "walks"}, False).startswith("✓")
    assert rehearsal_markdown({"clean": False, "fell": False, "message": "walks"}, False).startswith("⚠️")
    assert rehearsal_markdown({"clean": False, "fell": True, "message": "falls"}, True).startswith("✗")
    assert "before your last edit" in rehearsal_markdown({"fell": True, "message": "falls"}, True)
    assert "(95 s to rehearse)" in rehearsal_markdown({"fell": True, "message": "falls"}, False, wall_s=95.2)
