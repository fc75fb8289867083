"""A style that falls says so before Test is pressed (issue 13): the Rehearsal panel walks the style through the
sweep by itself after each open and edit, names where it falls, and a slower fast speed typed in the Style tab
walks; undo shows the remembered verdict at once."""

from __future__ import annotations

import shutil

import pytest

from tests.e2e.browser import copy_styles, engine_page, open_style, started_studio, wait_for_text, wait_until
from tests.studio.test_rehearse_after_edits import STUMBLY

pytestmark = pytest.mark.e2e

SWEEP_S = 4.0  # stand 1 s and the forward leg's start: stumbly falls 2 s in


def test_a_style_that_falls_is_rehearsed_by_itself_and_a_slower_speed_walks(tmp_path, artifacts):
    styles = copy_styles(tmp_path)
    shutil.copy(STUMBLY, styles / "g1" / "stumbly.json")
    with started_studio("g1", styles, rehearse_after_edits=True, rehearsal_duration_s=SWEEP_S) as studio:
        with engine_page(studio, 1000, 760) as page:
            open_style(page, studio, "stumbly")
            page.get_by_role("tab", name="Sample").click(force=True)
            wait_for_text(page, "falls at", timeout_ms=120_000)
            text = page.inner_text("body")
            assert "forward" in text and "% of its cycle" in text
            # The fall's sample, one click away: the Sample tab (its check, its timings) shows that sample.
            fell_in = studio.rehearsal.verdict(studio.session.style)["sample"]
            assert studio.sample_editor.sample_name != fell_in
            page.get_by_role("button", name=f"Show {fell_in}").click()
            wait_until(lambda: studio.sample_editor.sample_name == fell_in, 30, f"the Sample tab showing {fell_in}")
            wait_until(lambda: f"**{fell_in}**" in studio.sample_editor.feasibility.content, 60,
                       f"the edit-time check of {fell_in}")
            page.screenshot(path=str(artifacts / "studio_rehearsal_falls.png"))
            page.get_by_role("tab", name="Style").click(force=True)
            box = page.get_by_label("Fast (m/s)", exact=True)
            box.fill("0.3")
            page.screenshot(path=str(artifacts / "studio_style_speeds.png"))
            page.get_by_role("tab", name="Sample").click(force=True)
            wait_for_text(page, f"walks the {SWEEP_S:.0f} s sweep", timeout_ms=120_000)
            assert studio.session.style.velocities.x_max_mps == pytest.approx(0.3)
            page.screenshot(path=str(artifacts / "studio_rehearsal_walks.png"))
            page.get_by_role("tab", name="Style").click(force=True)
            page.get_by_role("button", name="Undo").click()
            page.get_by_role("tab", name="Sample").click(force=True)
            wait_for_text(page, "this version was rehearsed before", timeout_ms=60_000)
            assert "falls at" in page.inner_text("body")
