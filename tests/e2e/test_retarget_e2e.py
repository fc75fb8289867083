"""The Retarget workspace in the browser: import a clip, retarget it to go1 with SMR, watch it play beside the
source skeleton, scrub, export; a second run (STMR on a long clip) shows its progress, and Cancel stops it
having written nothing."""

from __future__ import annotations

import re

import pytest

from engine.motion_files import shared_root
from tests.conftest import ServedStudio
from tests.e2e.browser import engine_page, open_page, stall_ms, started_studio, text_input, wait_for_text

pytestmark = pytest.mark.e2e

TROT0 = "stmr_rl/datasets/trot0/trot0_keypoints.npz"
LONG_CLIP = "motion_imitation/retarget_keypoints/dog_run04_joint_pos.txt"


def clock(page) -> tuple[int, str]:
    m = re.search(r"Frame (\d+) of \d+ · [\d.]+ s · (playing|paused)", page.inner_text("body"))
    assert m, "no playback clock on the page"
    return int(m.group(1)), m.group(2)


def test_retarget_workspace(tmp_path, monkeypatch, artifacts):
    motions = tmp_path / "motions"
    monkeypatch.setenv("MOTION_STUDIO_MOTIONS", str(motions))
    studio = ServedStudio("go1")
    try:
        with open_page(studio.url, 1000, 760) as page:
            wait_for_text(page, "Job: idle")  # a quadruped opens on the Retarget workspace
            shared = shared_root()
            if shared is not None and (shared / "motions-src" / TROT0).is_file():
                box = text_input(page, "Import path")
                box.fill(TROT0)
                box.press("Enter")
                box.blur()
                wait_for_text(page, f"✓ {TROT0}", 30_000)  # the studio checked the path (inside motions-src)
                page.get_by_role("button", name="Import", exact=True).click()
                wait_for_text(page, "Imported source/trot0_keypoints.npz", 120_000)
                assert (motions / "source" / "trot0_keypoints.npz").is_file()
                stem = "trot0_keypoints"
            else:  # no shared data: the demo clip the engine makes itself
                stem = "trot"
            page.get_by_role("button", name="Run", exact=True).click()
            # SMR of a short clip takes milliseconds: its progress text may never reach the page, only the result
            wait_for_text(page, f"Result: go1/{stem}_smr.npz written", 300_000)
            assert (motions / "go1" / f"{stem}_smr.npz").is_file()
            wait_for_text(page, "contact IoU", 120_000)  # the metrics show once the result's meshes are loaded
            first, state = clock(page)
            assert state == "playing"
            page.wait_for_function(  # the result plays: the frame advances
                "f => { const m = document.body.innerText.match(/Frame (\\d+) of/); return m && Number(m[1]) !== f; }",
                arg=first, timeout=stall_ms(60_000))
            page.screenshot(path=str(artifacts / "retarget_playing.png"))

            # pause, then scrub: type a frame into the timeline's number box
            page.get_by_role("button", name="Play / pause", exact=True).click()
            page.wait_for_function("() => /Frame \\d+ of \\d+ · [\\d.]+ s · paused/.test(document.body.innerText)",
                                   timeout=stall_ms(60_000))
            slider_input = text_input(page, "Frame")
            slider_input.fill("12")
            slider_input.press("Enter")
            page.wait_for_function("() => /Frame 12 of \\d+ · [\\d.]+ s · paused/.test(document.body.innerText)",
                                   timeout=stall_ms(60_000))

            page.get_by_role("button", name="Export", exact=True).click()
            wait_for_text(page, f"Exported: motions/exports/go1_{stem}_smr.json", 120_000)
            assert (motions / "exports" / f"go1_{stem}_smr.json").is_file()

            # a second run on a long clip (1263 frames of dog mocap), cancelled: nothing written
            long_stem = stem
            if shared is not None and (shared / "motions-src" / LONG_CLIP).is_file():
                box = text_input(page, "Import path")
                box.fill(LONG_CLIP)
                box.press("Enter")
                wait_for_text(page, f"✓ {LONG_CLIP}", 30_000)
                page.get_by_role("button", name="Import", exact=True).click()
                wait_for_text(page, "Imported source/dog_run04_joint_pos.npz", 120_000)
                long_stem = "dog_run04_joint_pos"
            # STMR (minutes of BO + iLQR in MuJoCo): its progress shows while the engine works, then Cancel stops it
            method = text_input(page, "Method")
            method.click()
            page.get_by_role("option", name="stmr", exact=True).click()
            page.get_by_role("button", name="Run", exact=True).click()
            wait_for_text(page, "Retarget running: TMR: BO evaluation", 180_000)
            page.screenshot(path=str(artifacts / "retarget_running.png"))
            page.get_by_role("button", name="Cancel", exact=True).click()
            wait_for_text(page, "Retarget cancelled: nothing written", 120_000)
            page.screenshot(path=str(artifacts / "retarget_cancelled.png"))
            assert not list((motions / "go1").glob(f"{long_stem}_stmr*"))
            assert not list(motions.rglob("*.tmp"))
    finally:
        studio.stop()


# ---------------------------------------------------------------- STMR: the result plays in physics
STMR_BUDGET = 2  # α = 1, then log2 α = −1 (the warm start): trot0 falls at α = 1 on go1 and stands at α = 0.5
STMR_SEGMENTS = 2  # as cheap as S = 1 (the cost is the BO evaluations), and it draws a boundary inside the clip


def _scene_positions(page, root: str, names: list[str]) -> list[list[float]] | None:
    """Positions (parent frame) of the browser's three.js nodes ``root/<name>``: what the page draws."""
    return page.evaluate("""([root, names]) => {
        const m = window.__viserMutable; if (!m || !m.nodeRefFromName) return null;
        const out = [];
        for (const n of names) { const o = m.nodeRefFromName[root + '/' + n]; if (!o) return null;
                                 out.push([o.position.x, o.position.y, o.position.z]); }
        return out; }""", [root, names])


def _max_diff(page, root: str, names: list[str], expected) -> float:
    import numpy as np

    got = _scene_positions(page, root, names)
    return float("inf") if got is None else float(np.abs(np.asarray(got) - np.asarray(expected)).max())


def _kinematic_frames(result, smr) -> dict[int, int]:
    """Frames k of the re-timed result whose time maps (s_α, piecewise linear over the S equal segments of
    SMR's clip, from the α and knots stored in the result) exactly onto an SMR frame: {k: SMR frame}."""
    import numpy as np

    knots = np.asarray(result.extra["segment_knots_s"], float)
    source_knots = np.linspace(0.0, (smr.frames - 1) / smr.fps, len(knots))
    x = np.interp(np.arange(result.frames) / result.fps, knots, source_knots) * smr.fps
    return {int(k): int(round(x[k])) for k in np.flatnonzero(np.abs(x - np.round(x)) < 1e-6)}


def test_stmr_result_plays_in_physics_beside_the_smr_ghost(tmp_path, monkeypatch, artifacts):
    """A short STMR run (trot0 on go1, BO budget 2, S = 2) finishes in the browser and plays: the robot the page
    draws is the open-loop replay in physics (its body poses move over playback time), the see-through ghost is
    SMR's motion at the same point of the motion (equal to the robot at the start, apart where the physics did
    not follow), and the α segments are drawn over the Frame slider with the result's α."""
    import numpy as np

    from engine.jobs import body_poses
    from engine.retarget.importers import import_source
    from engine.retarget.motion import RobotMotion
    from tests.e2e.browser import close_software_webgl_notice, wait_value

    shared = shared_root()
    if shared is None or not (shared / "motions-src" / TROT0).is_file():
        pytest.skip("needs the shared STMR clips (trot0)")
    motions = tmp_path / "motions"
    monkeypatch.setenv("MOTION_STUDIO_MOTIONS", str(motions))
    (motions / "source").mkdir(parents=True)
    import_source(shared / "motions-src" / TROT0).save(motions / "source" / "trot0.npz")
    with started_studio("go1") as studio:
        panel = studio.retarget
        with engine_page(studio, 900, 700, ready_text="Job: idle", load_s=180) as page:
            for label, option in (("Source", "source/trot0.npz"), ("Method", "stmr")):
                text_input(page, label).click()
                page.get_by_role("option", name=option, exact=True).click()
            for label, value in (("TMR budget", STMR_BUDGET), ("TMR segments", STMR_SEGMENTS)):
                box = text_input(page, label)
                box.fill(str(value))
                box.press("Enter")
            wait_value(lambda: (panel.source.value, panel.method.value, panel.budget.value, panel.segments.value)
                       == ("source/trot0.npz", "stmr", STMR_BUDGET, STMR_SEGMENTS), 30, "the choices to reach the studio",
                       page)
            page.get_by_role("button", name="Run", exact=True).click()
            wait_for_text(page, "Result: go1/trot0_stmr.npz written", 300_000)
            result = RobotMotion.load(motions / "go1" / "trot0_stmr.npz")
            smr = RobotMotion.load(motions / "go1" / "trot0_stmr.smr.npz")
            alpha = [float(a) for a in result.extra["alpha"]]
            knots = [float(k) for k in result.extra["segment_knots_s"]]
            assert result.method == "stmr" and smr.method == "smr" and len(alpha) == STMR_SEGMENTS
            wait_for_text(page, f"segment 1 of {STMR_SEGMENTS}, α {alpha[0]:.2f}", 120_000)  # the playback clock
            wait_for_text(page, "Show SMR ghost")

            # the α segments over the Frame slider: one block per segment with its α, marks at the boundaries
            bar = page.evaluate("""() => [...document.querySelectorAll('.alpha-segment')].map(e => {
                const r = e.getBoundingClientRect();
                return {alpha: Number(e.dataset.alpha), text: e.innerText, left: r.left, right: r.right, top: r.top}; })""")
            assert [round(b["alpha"], 3) for b in bar] == [round(a, 3) for a in alpha], bar
            assert [b["text"] for b in bar] == [f"α {a:.2f}" for a in alpha]
            marks = page.evaluate("() => [...document.querySelectorAll('.mantine-Slider-markLabel')].map(e => e.innerText)")
            assert all(f"{k:.2f} s" in marks for k in knots), (marks, knots)
            track = page.evaluate("""top => { const t = [...document.querySelectorAll('.mantine-Slider-track')]
                .map(e => e.getBoundingClientRect()).filter(r => r.top > top).sort((a, b) => a.top - b.top)[0];
                return {left: t.left, right: t.right}; }""", bar[0]["top"])
            span = track["right"] - track["left"]
            assert abs(bar[0]["left"] - track["left"]) < 3 and abs(bar[-1]["right"] - track["right"]) < 3, (bar, track)
            for b, t0, t1 in zip(bar, knots, knots[1:]):  # each block spans its segment's share of the slider
                duration = (result.frames - 1) / result.fps
                assert abs(b["right"] - b["left"] - span * (min(t1, duration) - t0) / duration) < 4, (b, track, knots)

            # the robot the page draws moves while it plays
            names, body_pos, _ = body_poses(result)  # the open-loop replay in MuJoCo (the file's qpos)
            _, smr_pos, _ = body_poses(smr)
            start = _scene_positions(page, "/retarget/robot", names[:1])
            wait_value(lambda: _max_diff(page, "/retarget/robot", names[:1], start) > 0.005, 60,
                       "the playing robot to move", page)

            # paused and scrubbed: the robot is the physics replay's frame, the ghost SMR's frame at s_α(t)
            page.get_by_role("button", name="Play / pause", exact=True).click()
            page.wait_for_function("() => /Frame \\d+ of \\d+ · [\\d.]+ s · paused/.test(document.body.innerText)",
                                   timeout=stall_ms(60_000))
            frames = _kinematic_frames(result, smr)
            gap = {k: float(np.abs(body_pos[k] - smr_pos[f]).max()) for k, f in frames.items()}
            far = max(gap, key=gap.__getitem__)
            assert 0 in frames and gap[0] < 1e-4, "the replay starts from SMR's first frame"
            assert gap[far] > 0.01, f"physics and SMR's motion never part ({gap[far]:.4f} m)"
            slider = text_input(page, "Frame")
            for k in sorted({0, far}):
                slider.fill(str(k))
                slider.press("Enter")
                page.wait_for_function("k => new RegExp(`Frame ${k} of \\\\d+ · [\\\\d.]+ s · paused`)"
                                       ".test(document.body.innerText)", arg=k, timeout=stall_ms(60_000))
                wait_value(lambda: _max_diff(page, "/retarget/robot", names, body_pos[k]) < 1e-3, 60,
                           f"the page's robot to show the replay's frame {k}", page)
                wait_value(lambda: _max_diff(page, "/retarget/ghost", names, smr_pos[frames[k]]) < 1e-3, 60,
                           f"the page's ghost to show SMR's frame {frames[k]} (result frame {k})", page)
            # at the far frame the page shows them apart by what the physics did not follow
            drawn_gap = np.abs(np.asarray(_scene_positions(page, "/retarget/robot", names))
                               - np.asarray(_scene_positions(page, "/retarget/ghost", names))).max()
            assert drawn_gap > 0.01 - 2e-3, drawn_gap
            close_software_webgl_notice(page)
            page.get_by_text("α segments", exact=False).first.scroll_into_view_if_needed()
            page.screenshot(path=str(artifacts / "retarget_stmr_physics.png"))
            # a close-up for the eye (the camera moved by the test): the robot in physics, SMR's ghost in blue
            from studio.panels.retarget_panel import PLAYBACK_OFFSET

            base = body_pos[far, 0] + np.asarray(PLAYBACK_OFFSET)
            eye = base + np.array([0.55, -0.85, 0.35])
            for client in studio.server.get_clients().values():
                client.camera.look_at = tuple(base)
                client.camera.position = tuple(eye)
            # three.js is y-up (viser rotates the z-up world about the origin): compare distances to the origin
            page.wait_for_function("""r => { const c = window.__viserMutable && window.__viserMutable.camera;
                return c && Math.abs(c.position.length() - r) < 0.05; }""",
                                   arg=float(np.linalg.norm(eye)), timeout=stall_ms(60_000))
            close_software_webgl_notice(page)
            page.locator("canvas").first.screenshot(path=str(artifacts / "retarget_stmr_closeup.png"))
