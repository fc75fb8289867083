"""An edit the robot could not walk is flagged in the Sample panel (sample, phase, advice)
before Test is pressed; undo and the warning goes. Both a pose the legs cannot reach (the pelvis
too high) and a curve faster than the robot follows (a swing apex 10 ms before touchdown)."""

from __future__ import annotations


import pytest

from engine.gait.curve_editing import KnotRef
from tests.e2e.browser import copy_styles, engine_page, started_studio, wait_for_text

pytestmark = pytest.mark.e2e


def test_an_infeasible_edit_is_flagged_and_undo_clears_it(tmp_path, artifacts):
    styles = copy_styles(tmp_path)
    with started_studio("g1", styles) as studio:
        with engine_page(studio, 1000, 720) as page:
            page.get_by_role("tab", name="Sample").click(force=True)
            editor = studio.sample_editor
            editor.select("forward_fast")
            wait_for_text(page, "nothing in the way of walking it", timeout_ms=120_000)
            # The pelvis slider to the top of its range: the knees cannot reach the feet straight.
            assert editor.set_attribute("pelvis_height_m", studio.session.ctx.pelvis_height_range_m[1])
            wait_for_text(page, "knee straight", timeout_ms=120_000)
            text = page.inner_text("body")
            assert "forward_fast" in text and "% of the cycle" in text and "lower the pelvis" in text
            page.screenshot(path=str(artifacts / "studio_sample_feasibility_warning.png"))
            _undo_until_the_warning_goes(page, "knee straight")
            page.screenshot(path=str(artifacts / "studio_sample_feasibility_cleared.png"))
            # A curve faster than the robot follows (issue 13): the swing apex of the left foot moved to
            # 10 ms before touchdown, the foot would drop 7 cm in 10 ms. The check names the curve and the phase.
            curves = studio.curve_editor
            assert curves is not None
            curves.set_sample("forward_fast")
            curves.set_active_channel("left_foot.z")
            curves.select([KnotRef("left_foot.z", 1)])
            swing_s = studio.session.style.sample("forward_fast").intervals.swing_duration_s("left")
            assert curves.set_knot_values(t_s=swing_s - 0.01).ok
            wait_for_text(page, "left_foot.z curve", timeout_ms=120_000)
            text = page.inner_text("body")
            assert "forward_fast" in text and "% of the cycle" in text and "further apart" in text
            page.screenshot(path=str(artifacts / "studio_sample_feasibility_curve_rate.png"))
            _undo_until_the_warning_goes(page, "left_foot.z curve")


def _undo_until_the_warning_goes(page, warning: str) -> None:
    """Undo (Style tab), back to the Sample tab: the check clears and ``warning`` is gone."""
    page.get_by_role("tab", name="Style").click(force=True)
    page.get_by_role("button", name="Undo").click()
    page.get_by_role("tab", name="Sample").click(force=True)
    wait_for_text(page, "nothing in the way of walking it", timeout_ms=120_000)
    assert warning not in page.inner_text("body")


def test_a_pelvis_bob_the_balance_plan_cannot_follow_is_flagged_and_softening_it_clears_it(tmp_path, artifacts):
    """The check's balance part (engine/gait/zmp_feasibility.py) in the browser: an animator's style whose pelvis
    bobs ±3 cm twice a cycle. The Sample tab says the CoP would have to leave a sole (sample, phase, what to do);
    typing smaller values for the curve's four bumps clears it."""
    import dataclasses

    from engine.gait.style import StyleContext, load_style, save_style
    from tests.e2e.browser import open_style
    from tests.gait.test_feasibility import pelvis_bob

    styles = copy_styles(tmp_path)
    neutral = load_style(styles / "g1" / "neutral.json", StyleContext.for_robot("g1"))
    bouncy = dataclasses.replace(neutral, name="bouncy", samples={k: pelvis_bob(v, 0.03) for k, v in neutral.samples.items()})
    save_style(styles / "g1" / "bouncy.json", bouncy)
    with started_studio("g1", styles) as studio:
        with engine_page(studio, 1000, 720) as page:
            open_style(page, studio, "bouncy")
            page.get_by_role("tab", name="Sample").click(force=True)
            studio.sample_editor.select("in_place")
            wait_for_text(page, "soften the pelvis height curve", timeout_ms=120_000)
            text = page.inner_text("body")
            assert "in_place" in text and "% of the cycle" in text and "beyond the" in text and "sole" in text
            page.screenshot(path=str(artifacts / "studio_sample_feasibility_balance.png"))
            curves = studio.curve_editor
            assert curves is not None
            curves.set_sample("in_place")
            curves.set_active_channel("pelvis.z")
            for i in (1, 3, 5, 7):  # the bumps: ±3 cm → ±2 mm
                curves.select([KnotRef("pelvis.z", i)])
                assert curves.set_knot_values(value=0.002 * (1.0 if i % 4 == 1 else -1.0)).ok
            wait_for_text(page, "nothing in the way of walking it", timeout_ms=120_000)
            assert "soften the pelvis height curve" not in page.inner_text("body")
