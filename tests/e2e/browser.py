"""Headless Chromium (Debian's /usr/bin/chromium) driven by Playwright, for e2e tests."""

from __future__ import annotations

import contextlib
import io
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
#: Every wall-clock timeout in the e2e tests is a stall guard (a test that passes returns as soon as its
#: condition holds), so it is scaled generously: machines here differ 3x in speed and a software-WebGL
#: page on a loaded slow one answers many times slower still. ``E2E_STALL_SCALE`` overrides the factor.
STALL_SCALE = float(os.environ.get("E2E_STALL_SCALE", "4") or 4)


def stall_s(seconds: float) -> float:
    """A stall guard of ``seconds`` on this project's reference machine, scaled for slower ones."""
    return seconds * STALL_SCALE


def stall_ms(milliseconds: float) -> float:
    return milliseconds * STALL_SCALE
ARGS = [
    "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-quic",
]


def copy_styles(tmp_path: Path, robot: str = "g1") -> Path:
    """A styles folder under ``tmp_path`` holding copies of the shipped styles of ``robot`` (tests edit and
    save there, never in the repository)."""
    from tests.conftest import REPO

    styles = tmp_path / "styles"
    (styles / robot).mkdir(parents=True)
    for p in (REPO / "styles" / robot).glob("*.json"):
        shutil.copy(p, styles / robot / p.name)
    return styles


@contextlib.contextmanager
def open_page(url: str, width: int = 900, height: int = 640):
    playwright = pytest.importorskip("playwright.sync_api")

    if not os.path.exists(CHROMIUM):
        pytest.fail("chromium is not installed: `make test` installs Debian's chromium")
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
        page = browser.new_page(viewport={"width": width, "height": height})
        page.set_default_timeout(stall_ms(60_000))
        slowdown = float(os.environ.get("E2E_CPU_SLOWDOWN", "1") or 1)
        if slowdown > 1:  # a slower machine's page, emulated: Chromium's CPU throttling (e.g. 3 or 6)
            page.context.new_cdp_session(page).send("Emulation.setCPUThrottlingRate", {"rate": slowdown})
        page.goto(url)
        try:
            yield page
        finally:
            browser.close()


@contextlib.contextmanager
def started_studio(robot: str = "g1", styles_folder: Path | None = None, **options):
    """A :class:`studio.app.Studio` of ``robot`` started on a free local port (``styles_folder``: a copy made by
    :func:`copy_styles`, or None for the retarget-only robots; ``options``: the Studio's keyword options), stopped
    however the test ends."""
    from studio.app import Studio
    from tests.conftest import free_port

    kwargs = {} if styles_folder is None else {"styles_folder": styles_folder}
    studio = Studio(robot, port=free_port(), **kwargs, **options).start()
    try:
        yield studio
    finally:
        studio.stop()


@contextlib.contextmanager
def engine_page(studio, width: int, height: int, ready_text: str = "Engine running", load_s: float = 240.0):
    """A page on ``studio`` once its models have loaded and the page shows ``ready_text``, with viser's
    software-WebGL notice closed (a loaded machine builds the models slowly: ``load_s`` is a stall guard)."""
    assert studio.loaded.wait(stall_s(load_s)), "the studio's models did not load"
    with open_page(studio.url, width, height) as page:
        wait_for_text(page, ready_text, timeout_ms=240_000)
        close_software_webgl_notice(page)
        yield page


def text_input(page, label: str):
    """viser's text and number inputs carry no accessible name: the text input in the row of ``label``."""
    page.wait_for_function("l => [...document.querySelectorAll('label')].some(e => e.innerText.trim() === l)", arg=label)
    page.evaluate("""l => {
        const label = [...document.querySelectorAll('label')].find(e => e.innerText.trim() === l);
        let n = label;
        while (n && !n.querySelector('input:not([type=hidden]):not([type=checkbox])')) n = n.parentElement;
        n.querySelector('input:not([type=hidden]):not([type=checkbox])').setAttribute('data-e2e', l);
    }""", label)
    return page.locator(f"input[data-e2e='{label}']")


def wait_for_text(page, text: str, timeout_ms: int = 60_000) -> None:
    page.wait_for_function("t => document.body.innerText.includes(t)", arg=text, timeout=stall_ms(timeout_ms))


def wait_until(predicate, timeout_s: float, what: str, poll_s: float = 0.1) -> None:
    """Poll ``predicate`` until it holds (a condition, not a fixed sleep); fail naming ``what``."""
    import time

    deadline = time.monotonic() + stall_s(timeout_s)
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(poll_s)
    pytest.fail(f"timed out after {stall_s(timeout_s):g} s waiting for {what}")


def close_software_webgl_notice(page) -> None:
    """Close viser's "Software WebGL rendering detected" notice (it covers the canvas's top-left corner)."""
    notice = page.locator(".mantine-Notification-root", has_text="Software WebGL").locator("button")
    if notice.count():
        try:
            notice.first.click(timeout=stall_ms(10_000))
        except Exception:  # noqa: BLE001 - it may have closed by itself
            pass


def wait_value(predicate, timeout_s: float, what: str, page=None, poll_ms: int = 250):
    """Poll ``predicate`` until it returns something truthy and return that; while a page is open, poll through
    the page (``wait_for_timeout`` keeps its event loop going); fail naming ``what``."""
    import time

    deadline = time.monotonic() + stall_s(timeout_s)
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        if page is not None:
            page.wait_for_timeout(poll_ms)
        else:
            time.sleep(poll_ms / 1000)
    pytest.fail(f"timed out waiting for {what}")


def canvas_pixels(page) -> np.ndarray:
    """RGB pixels of the 3D canvas as seen on screen."""
    from PIL import Image

    png = page.locator("canvas").first.screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)


def robot_pixel_count(rgb: np.ndarray) -> int:
    """Pixels dark enough to be robot (G1/TALOS dark parts), not the light grid or background."""
    return int(np.sum(rgb.max(axis=2) < 90))


def open_style(page, studio, name: str) -> None:
    """Style tab → pick ``name`` → Open, as the animator clicks it; returns once the session has it."""
    page.get_by_role("tab", name="Style").click(force=True)
    studio.style_browser.dropdown.value = name
    page.get_by_role("button", name="Open").click()
    wait_until(lambda: studio.session.style.name == name, 60, "the style to open")
