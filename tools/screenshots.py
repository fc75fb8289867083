"""Take the README's studio screenshots (edit mode, test mode, curve editor, plots).

Runs the studio in this process with a scratch copy of the styles and drives it in headless
Chromium: ``.venv/bin/python tools/screenshots.py``.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from studio.app import Studio  # noqa: E402
from tests.conftest import free_port  # noqa: E402
from tests.e2e.browser import open_page, wait_for_text  # noqa: E402

OUT = REPO / "docs" / "images"


def main() -> int:
    OUT.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp())
    for robot in ("g1",):
        shutil.copytree(REPO / "styles" / robot, scratch / robot)
    studio = Studio("g1", port=free_port(), styles_folder=scratch).start()
    try:
        studio.loaded.wait(60)
        with open_page(studio.url, 1400, 860) as page:
            wait_for_text(page, "Engine running")
            notice = page.locator(".mantine-Notification-root", has_text="Software WebGL").locator("button")
            if notice.count():
                notice.first.click()
            page.get_by_role("button", name="Edit").click()
            wait_for_text(page, "edit mode")
            studio.sample_editor.select("forward_slow")
            page.get_by_text("Sample", exact=True).first.click()
            time.sleep(10)
            page.screenshot(path=str(OUT / "edit_mode.png"))
            page.get_by_text("Curves", exact=True).first.click()
            editor = studio.curve_editor
            editor.set_active_channel("joints.left_shoulder_pitch_joint")
            editor.show_channel("joints.right_shoulder_pitch_joint")
            editor.show_channel("joints.left_elbow_joint")
            editor.frame_all()
            client = next(iter(studio.server.get_clients().values()))
            editor.look_at_graph(client)
            time.sleep(5)
            page.screenshot(path=str(OUT / "curve_editor.png"))
            page.get_by_text("Robot", exact=True).first.click()
            page.get_by_role("button", name="Test").click()
            time.sleep(1.5)
            page.get_by_role("button", name="▲ forward").hover()
            page.mouse.down()
            time.sleep(8)
            page.screenshot(path=str(OUT / "test_mode.png"))
            page.mouse.up()
            page.get_by_text("Plots", exact=True).first.click()
            time.sleep(3)
            page.screenshot(path=str(OUT / "plots.png"))
    finally:
        studio.stop()
        shutil.rmtree(scratch, ignore_errors=True)
    print("wrote", *sorted(p.name for p in OUT.glob("*.png")))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
