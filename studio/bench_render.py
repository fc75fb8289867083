"""``studio bench render``: what the studio's display settings cost a browser, measured side by side.

One studio (a real engine process behind it) in Test mode walking forward (the joystick's forward held the
whole run), one headless Chromium tab (Debian's, software
WebGL: the case of a machine without a GPU) rendering it. The shadow setting is switched back and forth
``rounds`` times; in each window of ``window_s`` seconds the tab's drawn frames (requestAnimationFrame) and
the engine's simulated time against the wall clock are counted. Printed per setting: the median frames per
second the tab drew, the median real-time factor of the simulation meanwhile, and the ratio against
shadows on (the studio's default is off; ``studio serve --shadows`` or the Robot tab's checkbox turn
them on).
"""

from __future__ import annotations

import shutil
import statistics
import tempfile
import time
from pathlib import Path

FRAMES_JS = ("() => { if (!window.__benchFrames) { window.__benchFrames = 0; const tick = () => "
             "{ window.__benchFrames++; requestAnimationFrame(tick); }; requestAnimationFrame(tick); } "
             "return window.__benchFrames; }")


def bench_render(robot: str = "g1", rounds: int = 3, window_s: float = 8.0, settle_s: float = 3.0) -> list[dict]:
    from playwright.sync_api import sync_playwright

    from engine.gait.style import styles_dir
    from studio.app import Studio
    from studio.bench_soak import _free_port

    scratch = Path(tempfile.mkdtemp(prefix="motion-studio-render-"))
    shutil.copytree(styles_dir(robot), scratch / robot, ignore=shutil.ignore_patterns(".autosave"))
    studio = Studio(robot, port=_free_port(), styles_folder=scratch).start()
    samples: dict[bool, list[tuple[float, float]]] = {True: [], False: []}

    def hold_forward(duration_s: float) -> None:
        end = time.monotonic() + duration_s
        while time.monotonic() < end:
            studio.drive.hold(0, 1.0)  # as a held ▲ forward button repeats
            time.sleep(0.1)
    try:
        if not studio.loaded.wait(180):
            raise RuntimeError("the studio did not load its robot within 180 s")
        studio.drive.set_mode("test")
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=shutil.which("chromium") or "/usr/bin/chromium",
                                        args=["--no-sandbox", "--enable-unsafe-swiftshader"])
            page = browser.new_page(viewport={"width": 1000, "height": 700})
            page.goto(f"http://127.0.0.1:{studio.server.get_port()}/", timeout=120_000)
            page.wait_for_selector("canvas", timeout=120_000)
            page.evaluate(FRAMES_JS)
            for _ in range(rounds):
                for shadows in (True, False):
                    studio.set_shadows(shadows)
                    hold_forward(settle_s)
                    frames0, wall0 = int(page.evaluate(FRAMES_JS)), time.monotonic()
                    sim0 = studio.view.last_frame.sim_time_s if studio.view.last_frame else 0.0
                    hold_forward(window_s)
                    frames1, wall1 = int(page.evaluate(FRAMES_JS)), time.monotonic()
                    sim1 = studio.view.last_frame.sim_time_s if studio.view.last_frame else 0.0
                    samples[shadows].append(((frames1 - frames0) / (wall1 - wall0), (sim1 - sim0) / (wall1 - wall0)))
            browser.close()
    finally:
        studio.stop()
        shutil.rmtree(scratch, ignore_errors=True)
    fps_on = statistics.median(f for f, _ in samples[True])
    rows = []
    for shadows in (True, False):
        fps = statistics.median(f for f, _ in samples[shadows])
        rows.append({"section": "render", "robot": robot, "shadows": "on" if shadows else "off (default)",
                     "tab_fps": round(fps, 2), "real_time_factor": round(statistics.median(r for _, r in samples[shadows]), 2),
                     "fps_vs_shadows_on": round(fps / fps_on, 1) if fps_on > 0 else float("inf"),
                     "windows": f"{rounds} x {window_s:g} s"})
    return rows
