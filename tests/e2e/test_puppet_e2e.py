"""The Puppeteer workspace in the browser: G1 stands under the whole-body controller while a held-out CMU clip
drives its arms (LWL2); the status counts frames and capsule collisions; two seconds of the arms become the
in_place sample's arm curves and are undone; Stop returns to standing."""

from __future__ import annotations

import pytest

from engine.retarget.humanoid_arm.puppet_session import puppet_clips
from tests.conftest import ServedStudio
from tests.e2e.browser import open_page, wait_for_text

pytestmark = pytest.mark.e2e

FRAMES_RE = r"Puppet: (\d+) frames"


def test_puppeteer_drives_g1_arms_from_a_clip(artifacts):
    clips = puppet_clips()
    if not clips:
        pytest.skip("shared mocap clips absent (set MOTION_STUDIO_SHARED)")
    studio = ServedStudio("g1")
    try:
        with open_page(studio.url, 1000, 760) as page:
            page.get_by_role("tab", name="Mocap").click()  # the mocap workspaces share one tab (one row of tabs)
            page.get_by_role("tab", name="Puppet").click()
            wait_for_text(page, "Puppet: idle")
            page.get_by_role("button", name="Start puppet").click()
            # the engine loads LWL2 and streams telemetry: wait until 30 puppet frames ran (simulated 0.5 s)
            page.wait_for_function(
                "re => { const m = document.body.innerText.match(new RegExp(re)); return m && +m[1] >= 30; }",
                arg=FRAMES_RE, timeout=240_000)
            text = page.inner_text("body")
            assert "LWL2" in text and "datagrams" in text
            page.screenshot(path=str(artifacts / "puppet_running.png"))
            # two seconds of the arms become the in_place sample's arm curves (one undoable edit), then undo
            page.get_by_role("button", name="Record gesture").click()
            wait_for_text(page, "Recorded", 240_000)
            page.get_by_role("button", name="Use as arm curves").click()
            wait_for_text(page, "in_place: 11 arm curves with 8 knots", 60_000)
            page.screenshot(path=str(artifacts / "puppet_gesture_applied.png"))
            page.get_by_role("button", name="Undo style edit").click()
            wait_for_text(page, "undid gesture → in_place arm curves", 60_000)
            page.get_by_role("button", name="Stop puppet").click()
            wait_for_text(page, "Puppet: idle")
    finally:
        studio.stop()
