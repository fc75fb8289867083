"""``studio bench soak --minutes M --clients C``: drive a running studio for M minutes (issue 14).

The studio runs in this process (a real engine process behind it) in Test mode. C headless WebSocket
clients speak viser's protocol (the subprotocol handshake and a camera message, as a browser tab does)
and count what the server streams to them; T browser tabs (Debian's headless Chromium through playwright,
software WebGL) render the studio and count the frames they draw (requestAnimationFrame). Meanwhile the joystick is held (forward, then turning), the
pelvis is pushed every 10 s and a sample attribute is edited every 5 s (through the style session, so
each edit is validated, autosaved and sent to the engine).

Reported: RSS of the studio and of the engine at the end of warm-up and at the end (growth in %),
WebSocket messages and bytes per second per client, frames per second each browser tab drew, frames per second the studio received from the
engine, sim-clock drift against the wall clock (Δsim/Δwall − 1 over the measured window, playback speed
1), engine restarts, and every exception seen (logging records with a traceback, thread exceptions,
error notices).
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
import threading
import time
from pathlib import Path


def _rss_mb(pid: int | None) -> float:
    if pid is None:
        return float("nan")
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


class _Client(threading.Thread):
    def __init__(self, url: str, stop: threading.Event):
        super().__init__(daemon=True, name="soak-client")
        self.url, self.stop = url, stop
        self.messages = 0
        self.bytes = 0
        self.error = ""
        self.window: tuple[int, int, float] | None = None  # (messages, bytes, t) at the start of the measurement

    def mark(self) -> None:
        self.window = (self.messages, self.bytes, time.monotonic())

    def rates(self) -> tuple[float, float]:
        if self.window is None:
            return float("nan"), float("nan")
        m0, b0, t0 = self.window
        dt = time.monotonic() - t0
        return (self.messages - m0) / dt, (self.bytes - b0) / dt / 1024.0

    def run(self) -> None:
        import msgspec
        import viser
        from websockets.sync.client import connect

        camera = msgspec.msgpack.encode({
            "type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [2.0, -2.2, 1.3],
            "image_height": 480, "image_width": 640, "fov": 1.0, "near": 0.01, "far": 1000.0,
            "look_at": [0.0, 0.0, 0.6], "up_direction": [0.0, 0.0, 1.0]})
        try:
            from websockets.typing import Subprotocol

            with connect(self.url, subprotocols=[Subprotocol(f"viser-v{viser.__version__}")], open_timeout=30,
                         max_size=None) as ws:
                ws.send(camera)
                while not self.stop.is_set():
                    try:
                        data = ws.recv(timeout=0.5)
                    except TimeoutError:
                        continue
                    self.messages += 1
                    self.bytes += len(data)
        except Exception as exc:  # noqa: BLE001 - reported
            self.error = f"{type(exc).__name__}: {exc}"


class _Tab(threading.Thread):
    """One headless Chromium tab on the studio, counting the frames it renders (requestAnimationFrame)."""

    COUNTER_JS = ("() => { if (!window.__soakFrames) { window.__soakFrames = 0; const tick = () => "
                  "{ window.__soakFrames++; requestAnimationFrame(tick); }; requestAnimationFrame(tick); } "
                  "return window.__soakFrames; }")

    def __init__(self, url: str, stop: threading.Event, mark: threading.Event):
        super().__init__(daemon=True, name="soak-tab")
        self.url, self.stop, self.mark_event = url, stop, mark
        self.error = ""
        self.loaded = threading.Event()
        self.window: tuple[int, float] | None = None
        self.last: tuple[int, float] | None = None
        self.finish = threading.Event()  # take a last sample and stop
        self.finished = threading.Event()

    def fps(self) -> float:
        if self.window is None or self.last is None or self.last[1] <= self.window[1]:
            return float("nan")
        return (self.last[0] - self.window[0]) / (self.last[1] - self.window[1])

    def run(self) -> None:
        try:
            from playwright.sync_api import sync_playwright

            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=shutil.which("chromium") or "/usr/bin/chromium",
                                            args=["--no-sandbox", "--enable-unsafe-swiftshader"])
                page = browser.new_page(viewport={"width": 800, "height": 600})
                page.goto(self.url, timeout=120_000)
                page.wait_for_selector("canvas", timeout=120_000)
                page.evaluate(self.COUNTER_JS)
                self.loaded.set()
                while not self.stop.is_set():
                    final = self.finish.is_set()
                    count = int(page.evaluate(self.COUNTER_JS))
                    now = time.monotonic()
                    if self.mark_event.is_set() and self.window is None:
                        self.window = (count, now)
                    elif self.window is not None:
                        self.last = (count, now)
                    if final:
                        break
                    self.finish.wait(1.0)
                self.finished.set()
                browser.close()
        except Exception as exc:  # noqa: BLE001 - reported
            self.error = f"tab: {type(exc).__name__}: {exc}"[:200]
            self.loaded.set()
            self.finished.set()


class _Errors(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.records: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(f"{record.name}: {record.getMessage()}"[:200])


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def bench_soak(minutes: float = 1.0, clients: int = 4, tabs: int = 2, robot: str = "g1") -> list[dict]:
    from dataclasses import replace

    from engine import protocol as msg
    from engine.gait.style import styles_dir
    from studio.app import Studio

    errors = _Errors()
    logging.getLogger().addHandler(errors)
    thread_errors: list[str] = []
    previous_hook = threading.excepthook
    threading.excepthook = lambda a: thread_errors.append(f"{a.thread.name if a.thread else '?'}: {a.exc_type.__name__}: "
                                                          f"{a.exc_value}"[:200])
    scratch = Path(tempfile.mkdtemp(prefix="motion-studio-soak-"))
    shutil.copytree(styles_dir(robot), scratch / robot, ignore=shutil.ignore_patterns(".autosave"))
    studio = Studio(robot, port=_free_port(), styles_folder=scratch).start()
    stop = threading.Event()
    frames: list[tuple[float, float]] = []
    original_update = studio.view.update

    def record(frame) -> None:
        original_update(frame)
        frames.append((time.monotonic(), frame.sim_time_s))

    studio.view.update = record  # type: ignore[method-assign]
    pool: list[_Client] = []
    browsers: list[_Tab] = []
    marked_event = threading.Event()
    try:
        if not studio.loaded.wait(180):
            raise RuntimeError("the studio did not load its robot within 180 s")
        studio.drive.set_mode("test")
        url = f"ws://127.0.0.1:{studio.server.get_port()}/"
        pool = [_Client(url, stop) for _ in range(clients)]
        for c in pool:
            c.start()
        browsers = [_Tab(f"http://127.0.0.1:{studio.server.get_port()}/", stop, marked_event) for _ in range(tabs)]
        for b in browsers:
            b.start()
        for b in browsers:  # the soak starts once every tab shows the studio
            b.loaded.wait(180)
        duration_s = 60.0 * minutes
        warmup_s = min(30.0, 0.25 * duration_s)
        t0 = time.monotonic()
        marked, frame_mark = False, 0
        rss0 = (float("nan"), float("nan"))
        restarts0 = studio.link.restarts
        next_push, next_edit, edits, pushes = t0 + 10.0, t0 + 5.0, 0, 0
        engine_pid0 = studio.link.pid
        while time.monotonic() - t0 < duration_s:
            now = time.monotonic()
            phase = int((now - t0) // 8) % 3  # forward, turning, standing still
            if phase == 0:
                studio.drive.hold(0, 1.0)
            elif phase == 1:
                studio.drive.hold(2, 1.0)
            if now >= next_push:
                studio.link.send(msg.ApplyPush((0.0, 25.0, 0.0), 0.2))
                pushes += 1
                next_push += 10.0
            session = studio.session
            style = session.style if session is not None else None
            if now >= next_edit and session is not None and style is not None:
                sample = style.samples["in_place"]
                width = 0.22 + 0.02 * (edits % 3)
                edited = replace(sample, attributes=replace(sample.attributes, stance_width_m=width))
                session.apply(style.with_sample("in_place", edited), "soak edit")
                edits += 1
                next_edit += 5.0
            if not marked and now - t0 >= warmup_s:
                marked = True
                rss0 = (_rss_mb(os.getpid()), _rss_mb(studio.link.pid))
                for c in pool:
                    c.mark()
                marked_event.set()
                frame_mark = len(frames)
            time.sleep(0.1)
        for b in browsers:  # each tab's last frame count
            b.finish.set()
        for b in browsers:
            b.finished.wait(60)
        rss1 = (_rss_mb(os.getpid()), _rss_mb(studio.link.pid))
        window = frames[frame_mark:] if marked else frames
        (w0, s0), (w1, s1) = window[0], window[-1]
        drift = (s1 - s0) / (w1 - w0) - 1.0
        rates = [c.rates() for c in pool]
        error_notices = [t for level, t in studio.notices if level == "error"]
        exceptions = (errors.records + thread_errors + [c.error for c in pool if c.error]
                      + [b.error for b in browsers if b.error] + error_notices)
        rows = [{
            "section": "soak", "what": "studio", "minutes": round(minutes, 2), "clients": clients,
            "studio_rss_mb": f"{rss0[0]:.0f}→{rss1[0]:.0f}", "studio_rss_growth_pct": round(100 * (rss1[0] / rss0[0] - 1), 1),
            "engine_rss_mb": f"{rss0[1]:.0f}→{rss1[1]:.0f}",
            "engine_rss_growth_pct": round(100 * (rss1[1] / rss0[1] - 1), 1) if studio.link.pid == engine_pid0 else "restarted",
            "engine_frames_per_s": round((len(window) - 1) / (w1 - w0), 1), "sim_clock_drift_pct": round(100 * drift, 2),
            "pushes": pushes, "edits": edits, "engine_restarts": studio.link.restarts - restarts0,
            "tabs": tabs, "tab_fps": ", ".join(f"{b.fps():.1f}" for b in browsers) or "-",
            "exceptions": len(exceptions), "load_avg_1min": round(os.getloadavg()[0], 1), "cpus": os.cpu_count(),
        }]
        for i, (m, kb) in enumerate(rates):
            rows.append({"section": "soak clients", "what": f"client {i}", "ws_messages_per_s": round(m, 1),
                         "ws_kib_per_s": round(kb, 1)})
        for text in exceptions[:20]:
            rows.append({"section": "soak exceptions", "what": "exception", "text": text})
        return rows
    finally:
        stop.set()
        for c in pool:
            c.join(5)
        for b in browsers:
            b.join(30)
        studio.stop()
        threading.excepthook = previous_hook
        logging.getLogger().removeHandler(errors)
        shutil.rmtree(scratch, ignore_errors=True)
