"""A style closed in the middle of a knot drag (issue 14): the drag ends quietly, nothing raises."""

from __future__ import annotations

from studio.panels.curve_editor import KnotRef
from tests.studio.test_curve_editor import SWING, editor, event, g1_ctx, server, session  # noqa: F401 - fixtures


def test_style_closed_mid_drag_ends_the_drag_without_error(editor, session):  # noqa: F811
    ref = KnotRef(SWING, 1)
    start = editor.knot_world_position(ref)
    goal = editor.world_position(SWING, 0.16, 0.09)
    editor.handle_knot_drag(ref, event("start", start, start))
    editor.handle_knot_drag(ref, event("update", start, goal))
    assert editor._drag is not None
    session.style = None  # the style is closed while the mouse button is still down
    editor.handle_knot_drag(ref, event("end", start, goal))  # the release arrives after the close
    assert editor._drag is None
    assert "cancel" not in editor.status


def test_finishing_a_drag_whose_style_is_gone_reverts_instead_of_raising(editor, session):  # noqa: F811
    ref = KnotRef(SWING, 1)
    start = editor.knot_world_position(ref)
    editor.handle_knot_drag(ref, event("start", start, start))
    editor.handle_knot_drag(ref, event("update", start, editor.world_position(SWING, 0.16, 0.09)))
    session.style = None
    editor._finish_drag()  # the path that called UndoGroup.cancel(), which does not exist
    assert editor._drag is None
