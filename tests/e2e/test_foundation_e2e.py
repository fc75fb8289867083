"""A user opens the studio: the robot stands on the grid; killing the engine does not break it."""

from __future__ import annotations

import os
import re
import signal

import numpy as np
import pytest

from tests.e2e.browser import stall_ms, canvas_pixels, open_page, robot_pixel_count, wait_for_text, wait_until

pytestmark = pytest.mark.e2e


def test_robot_stands_in_the_browser_and_survives_an_engine_kill(served_studio, artifacts):
    with open_page(served_studio.url) as page:
        wait_for_text(page, "Engine running")
        wait_until(lambda: robot_pixel_count(canvas_pixels(page)) > 300, 60, "the robot drawn (software WebGL)")
        page.screenshot(path=str(artifacts / "foundation_g1.png"))
        rgb = canvas_pixels(page)
        assert rgb.std() > 10, "canvas is blank"
        assert robot_pixel_count(rgb) > 300, "no robot visible on the canvas"

        text = page.inner_text("body")
        old_pid = int(re.search(r"pid (\d+)", text).group(1))
        assert old_pid in served_studio.engine_pids()
        os.kill(old_pid, signal.SIGKILL)
        wait_for_text(page, "stopped", timeout_ms=30_000)  # the notification tells the user
        page.wait_for_function(
            "old => { const m = document.body.innerText.match(/Engine running · pid (\\d+)/);"
            " return m && Number(m[1]) !== old; }", arg=old_pid, timeout=stall_ms(30_000))
        new_pid = int(re.search(r"Engine running · pid (\d+)", page.inner_text("body")).group(1))
        assert new_pid != old_pid and new_pid in served_studio.engine_pids()
        wait_until(lambda: robot_pixel_count(canvas_pixels(page)) > 300, 60, "the robot drawn after the restart")
        page.screenshot(path=str(artifacts / "foundation_g1_after_engine_restart.png"))
        assert robot_pixel_count(canvas_pixels(page)) > 300
