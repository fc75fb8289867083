"""A style that falls says so before Test is pressed (issue 13): the Rehearsal panel walks the style through the
sweep by itself after each open and edit, names where it falls, and the sample's splay set to 0 in the Sample tab
walks; undo shows the remembered verdict at once."""

from __future__ import annotations

import shutil

import pytest

from tests.e2e.browser import (copy_styles, engine_page, open_style, started_studio, text_input, wait_for_text,
                               wait_until)
from tests.studio.test_rehearse_after_edits import SPLAYED

pytestmark = pytest.mark.e2e

SWEEP_S = 4.0  # stand 1 s and the forward leg's start: splayed falls 0.9 s in, stepping in place


def test_a_style_that_falls_is_rehearsed_by_itself_and_an_edit_of_the_sample_it_names_walks(tmp_path, artifacts):
    styles = copy_styles(tmp_path)
    shutil.copy(SPLAYED, styles / "g1" / "splayed.json")
    with started_studio("g1", styles, rehearse_after_edits=True, rehearsal_duration_s=SWEEP_S) as studio:
        with engine_page(studio, 1000, 760) as page:
            open_style(page, studio, "splayed")
            page.get_by_role("tab", name="Sample").click(force=True)
            studio.sample_editor.select("forward_fast")  # the animator was looking at another sample
            wait_for_text(page, "falls at", timeout_ms=120_000)
            text = page.inner_text("body")
            assert "in_place" in text and "% of its cycle" in text
            # The fall's sample, one click away: the Sample tab (its check, its timings) shows that sample.
            fell_in = studio.rehearsal.verdict(studio.session.style)["sample"]
            assert fell_in == "in_place" and studio.sample_editor.sample_name != fell_in
            page.get_by_role("button", name=f"Show {fell_in}").click()
            wait_until(lambda: studio.sample_editor.sample_name == fell_in, 30, f"the Sample tab showing {fell_in}")
            wait_until(lambda: f"**{fell_in}**" in studio.sample_editor.feasibility.content, 60,
                       f"the edit-time check of {fell_in}")
            page.get_by_text("falls at").first.scroll_into_view_if_needed()
            page.screenshot(path=str(artifacts / "studio_rehearsal_falls.png"))
            splay = text_input(page, "Splay (rad)")
            splay.fill("0")
            splay.press("Enter")
            wait_until(lambda: studio.session.style.samples["in_place"].attributes.stance_splay_rad == 0.0, 30,
                       "in_place's splay at 0")
            wait_for_text(page, f"walks the {SWEEP_S:.0f} s sweep", timeout_ms=120_000)
            page.get_by_text(f"walks the {SWEEP_S:.0f} s sweep").first.scroll_into_view_if_needed()
            page.screenshot(path=str(artifacts / "studio_rehearsal_walks.png"))
            page.get_by_role("tab", name="Style").click(force=True)
            page.get_by_role("button", name="Undo").click()
            page.get_by_role("tab", name="Sample").click(force=True)
            wait_for_text(page, "this version was rehearsed before", timeout_ms=60_000)
            assert "falls at" in page.inner_text("body")
