"""The Retarget workspace in the browser: import a clip, retarget it to go1 with SMR, watch it play beside the
source skeleton, scrub, export; a second run (STMR on a long clip) shows its progress, and Cancel stops it
having written nothing."""

from __future__ import annotations

import re

import pytest

from engine.motion_files import shared_root
from tests.conftest import ServedStudio
from tests.e2e.browser import open_page, stall_ms, wait_for_text

pytestmark = pytest.mark.e2e

TROT0 = "stmr_rl/datasets/trot0/trot0_keypoints.npz"
LONG_CLIP = "motion_imitation/retarget_keypoints/dog_run04_joint_pos.txt"


def text_input(page, label: str):
    """viser's text and number inputs carry no accessible name: the text input in the row of ``label``."""
    page.wait_for_function("l => [...document.querySelectorAll('label')].some(e => e.innerText.trim() === l)", arg=label)
    page.evaluate("""l => {
        const label = [...document.querySelectorAll('label')].find(e => e.innerText.trim() === l);
        let n = label;
        while (n && !n.querySelector('input:not([type=hidden]):not([type=checkbox])')) n = n.parentElement;
        n.querySelector('input:not([type=hidden]):not([type=checkbox])').setAttribute('data-e2e', l);
    }""", label)
    return page.locator(f"input[data-e2e='{label}']")


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
