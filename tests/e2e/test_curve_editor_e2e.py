"""An animator drags a knot of the curve editor with the mouse in headless Chromium, then undoes
and redoes it with Ctrl+Z / Ctrl+Shift+Z. A minimal viser server hosts the editor (no engine)."""

from __future__ import annotations

import io
import shutil
import time

import numpy as np
import pytest
import viser

from studio.panels.curve_editor import CurveEditor, KnotRef, project_to_screen
from studio.style_session import StyleSession
from tests.conftest import REPO, free_port
from tests.e2e.browser import open_page, stall_s, wait_for_text

pytestmark = pytest.mark.e2e

SHOULDER = "joints.left_shoulder_pitch_joint"
ELBOW = "joints.left_elbow_joint"
RIGHT_SHOULDER = "joints.right_shoulder_pitch_joint"


def _wait(predicate, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + stall_s(timeout_s)
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.1)
    pytest.fail(f"timed out waiting for {what}")


def _pixels(page) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)


def _yellow_near(rgb: np.ndarray, x: float, y: float, r: int = 9) -> int:
    """Pixels of the selected (yellow) knot around (x, y); no curve colour is yellow."""
    patch = rgb[int(y) - r:int(y) + r + 1, int(x) - r:int(x) + r + 1]
    return int(np.sum((patch[..., 0] > 170) & (patch[..., 1] > 150) & (patch[..., 2] < 110)))


def test_drag_a_knot_with_the_mouse_then_undo_and_redo_with_the_keyboard(tmp_path, artifacts):
    shutil.copy(REPO / "styles" / "g1" / "neutral.json", tmp_path / "neutral.json")
    session = StyleSession(robot="g1", folder=tmp_path)
    assert session.open("neutral").ok
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    server.scene.set_up_direction("+z")
    server.gui.configure_theme(dark_mode=False, show_logo=False, control_width="medium")
    editor = CurveEditor(server, session)
    try:
        editor.set_active_channel(SHOULDER)
        editor.show_channel(ELBOW)
        editor.show_channel(RIGHT_SHOULDER)
        editor.set_active_channel(SHOULDER)
        editor.frame_all()
        editor.set_playhead(0.2)
        ref = KnotRef(SHOULDER, 1)  # t = 0.28 s, 0.47 rad: the arm's forward peak
        editor.handle_knot_click(ref)
        before = session.style.sample("forward_fast").curve(SHOULDER)

        with open_page(f"http://127.0.0.1:{server.get_port()}", width=1024, height=640) as page:
            _wait(lambda: len(server.get_clients()) == 1, 60, "the browser to connect")
            client = next(iter(server.get_clients().values()))
            _wait(lambda: client.camera.update_timestamp > 0, 60, "the browser's camera")
            wait_for_text(page, "Add knot at playhead")
            notice = page.locator(".mantine-Notification-root", has_text="Software WebGL").locator("button")
            if notice.count():
                notice.first.click()
            editor.look_at_graph(client)
            asked, t_asked = np.array(client.camera.position), time.time()
            # the browser echoes its camera once it has applied ours (the server-side state updates at once)
            _wait(lambda: client.camera.update_timestamp > t_asked
                  and np.allclose(client.camera.position, asked, atol=1e-3), 30, "the browser's camera on the graph")
            cam = client.camera
            box = page.locator("canvas").first.bounding_box()
            uv = project_to_screen(editor.knot_world_position(ref), cam.position, cam.wxyz, cam.fov, cam.aspect)
            assert uv is not None and 0 < uv[0] < 1 and 0 < uv[1] < 1
            x, y = box["x"] + uv[0] * box["width"], box["y"] + uv[1] * box["height"]
            # software WebGL is slow: wait until the knot is drawn where we projected it
            _wait(lambda: _yellow_near(_pixels(page), x, y) > 20, 30, f"the yellow (selected) knot at ({x:.0f}, {y:.0f})")

            # the value axis maps 0.1 rad to this many pixels (up is −y on screen)
            uv_up = project_to_screen(editor.world_position(SHOULDER, 0.28, 0.57), cam.position, cam.wxyz,
                                      cam.fov, cam.aspect)
            px_per_01 = (uv[1] - uv_up[1]) * box["height"]
            assert px_per_01 > 20, "the graph is too small on screen to drag precisely"
            page.mouse.move(x, y)
            page.mouse.down()
            for i in range(1, 5):  # straight up by 0.1 rad, in a few pointer moves
                page.mouse.move(x, y - px_per_01 * i / 4)
                if i == 1:
                    _wait(lambda: editor._drag is not None, 30, "the knot drag to start")
            # mid-drag: ghost of the old curve, live preview applied to the session
            _wait(lambda: session.style.sample("forward_fast").curve(SHOULDER) != before, 30, "the live preview")
            page.screenshot(path=str(artifacts / "curve_editor_drag.png"))
            assert session.style.sample("forward_fast").curve(SHOULDER) != before, "no live preview while dragging"
            page.mouse.up()

            def moved() -> bool:
                return editor._drag is None and session.undo_labels() == [f"move 1 knot(s) on {SHOULDER}"]

            _wait(moved, 10, "the drag to end as one undo entry")
            after = session.style.sample("forward_fast").curve(SHOULDER).knots[1]
            assert after.value == pytest.approx(0.57, abs=0.03), after
            assert after.t_s == pytest.approx(0.28, abs=1e-9), "a vertical drag keeps the knot's time"

            # Ctrl+Z / Ctrl+Shift+Z reach the Undo / Redo buttons through the editor's key listener
            page.mouse.click(box["x"] + 30, box["y"] + box["height"] - 30)  # focus the page, off the graph
            page.keyboard.press("Control+z")
            _wait(lambda: session.style.sample("forward_fast").curve(SHOULDER) == before, 10, "Ctrl+Z to undo")
            page.keyboard.press("Control+Shift+z")
            _wait(lambda: session.style.sample("forward_fast").curve(SHOULDER).knots[1].value > 0.5, 10,
                  "Ctrl+Shift+Z to redo")
            editor.select([KnotRef(SHOULDER, 1)])
            u2, v2 = project_to_screen(editor.knot_world_position(ref), cam.position, cam.wxyz, cam.fov, cam.aspect)
            x2, y2 = box["x"] + u2 * box["width"], box["y"] + v2 * box["height"]
            assert y2 < y - 0.5 * px_per_01, "the knot should be drawn higher after the edit"
            _wait(lambda: _yellow_near(_pixels(page), x2, y2) > 20, 30, "the redone knot drawn at its new place")
            page.screenshot(path=str(artifacts / "curve_editor.png"))
    finally:
        editor.close()
        server.stop()
