"""Take the README's studio screenshots (standing, edit mode, curve editor, test mode, plots).

Runs the studio in this process with a scratch copy of the styles and drives it in headless
Chromium: ``.venv/bin/python tools/screenshots.py [--out DIR]``. Each shot waits on simulated time
(the engine's clock), not the wall clock, so a slow or loaded machine takes the same pictures.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from studio.app import Studio  # noqa: E402
from tests.conftest import free_port  # noqa: E402
from tests.e2e.browser import close_software_webgl_notice, open_page, wait_for_text  # noqa: E402

OUT = REPO / "docs" / "images"


def sim_time_s(studio: Studio) -> float:
    frame = studio.view.last_frame
    return float(frame.sim_time_s) if frame is not None else 0.0


def wait_for(predicate, page, wall_cap_s: float = 600.0) -> None:
    deadline = time.monotonic() + wall_cap_s
    while not predicate():
        if time.monotonic() > deadline:
            raise TimeoutError("the studio did not get there")
        page.wait_for_timeout(250)


def let_simulate(studio: Studio, page, seconds: float, wall_cap_s: float = 600.0) -> None:
    """Let the engine run ``seconds`` of simulated time (the page keeps drawing meanwhile)."""
    start, deadline = sim_time_s(studio), time.monotonic() + wall_cap_s
    while sim_time_s(studio) < start + seconds and time.monotonic() < deadline:
        page.wait_for_timeout(250)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help="folder for the PNGs (default docs/images)")
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp())
    shutil.copytree(REPO / "styles" / "g1", scratch / "g1", ignore=shutil.ignore_patterns(".autosave"))
    studio = Studio("g1", port=free_port(), styles_folder=scratch).start()
    try:
        studio.loaded.wait(600)
        with open_page(studio.url, 1400, 860) as page:
            wait_for_text(page, "Engine running")
            close_software_webgl_notice(page)
            let_simulate(studio, page, 2.0)
            page.screenshot(path=str(out / "studio_g1.png"))
            page.get_by_role("button", name="Edit").click()
            wait_for_text(page, "edit mode")
            page.get_by_role("tab", name="Sample", exact=True).click()
            page.locator(f"[id='{studio.sample_editor.dropdown._impl.uuid}']").click()
            page.get_by_role("option", name="forward_slow", exact=True).click()
            wait_for(lambda: "edit mode (forward_slow)" in studio.robot_panel.status.content, page)  # Robot tab hidden
            let_simulate(studio, page, 4.0)
            page.screenshot(path=str(out / "edit_mode.png"))
            page.get_by_role("tab", name="Curves", exact=True).click()
            editor = studio.curve_editor
            editor.set_active_channel("joints.left_shoulder_pitch_joint")
            editor.show_channel("joints.right_shoulder_pitch_joint")
            editor.show_channel("joints.left_elbow_joint")
            editor.frame_all()
            page.get_by_role("button", name="Camera to graph").click()
            let_simulate(studio, page, 2.0)
            page.screenshot(path=str(out / "curve_editor.png"))
            page.get_by_role("tab", name="Robot", exact=True).click()
            page.get_by_role("button", name="Test").click()
            wait_for_text(page, "test mode")
            page.get_by_role("button", name="▲ forward").click()  # a tap latches forward (cruise) until ■ Stop
            page.wait_for_function("() => /Command: vx \\+0\\.[1-9]/.test(document.body.innerText)", timeout=600_000)
            let_simulate(studio, page, 6.0)
            page.screenshot(path=str(out / "test_mode.png"))
            page.get_by_role("tab", name="Plots", exact=True).click()
            let_simulate(studio, page, 4.0)
            page.screenshot(path=str(out / "plots.png"))
    finally:
        studio.stop()
        shutil.rmtree(scratch, ignore_errors=True)
    print("wrote", *sorted(p.name for p in out.glob("*.png")))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
