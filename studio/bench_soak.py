"""``studio bench soak --minutes M --clients C``: drive a running studio for M minutes (issue 14).

The studio runs in this process (a real engine process behind it) in Test mode. C headless WebSocket
clients speak viser's protocol (the subprotocol handshake and a camera message, as a browser tab does)
and count what the server streams to them. Meanwhile the joystick is held (forward, then turning), the
pelvis is pushed every 10 s and a sample attribute is edited every 5 s (through the style session, so
each edit is validated, autosaved and sent to the engine).

Reported: RSS of the studio and of the engine at the end of warm-up and at the end (growth in %),
WebSocket messages and bytes per second per client, frames per second the studio received from the
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


def bench_soak(minutes: float = 1.0, clients: int = 4, robot: str = "g1") -> list[dict]:
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
    try:
        if not studio.loaded.wait(180):
            raise RuntimeError("the studio did not load its robot within 180 s")
        studio.drive.set_mode("test")
        url = f"ws://127.0.0.1:{studio.server.get_port()}/"
        pool = [_Client(url, stop) for _ in range(clients)]
        for c in pool:
            c.start()
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
                frame_mark = len(frames)
            time.sleep(0.1)
        rss1 = (_rss_mb(os.getpid()), _rss_mb(studio.link.pid))
        window = frames[frame_mark:] if marked else frames
        (w0, s0), (w1, s1) = window[0], window[-1]
        drift = (s1 - s0) / (w1 - w0) - 1.0
        rates = [c.rates() for c in pool]
        error_notices = [t for level, t in studio.notices if level == "error"]
        exceptions = errors.records + thread_errors + [c.error for c in pool if c.error] + error_notices
        rows = [{
            "section": "soak", "what": "studio", "minutes": round(minutes, 2), "clients": clients,
            "studio_rss_mb": f"{rss0[0]:.0f}→{rss1[0]:.0f}", "studio_rss_growth_pct": round(100 * (rss1[0] / rss0[0] - 1), 1),
            "engine_rss_mb": f"{rss0[1]:.0f}→{rss1[1]:.0f}",
            "engine_rss_growth_pct": round(100 * (rss1[1] / rss0[1] - 1), 1) if studio.link.pid == engine_pid0 else "restarted",
            "engine_frames_per_s": round((len(window) - 1) / (w1 - w0), 1), "sim_clock_drift_pct": round(100 * drift, 2),
            "pushes": pushes, "edits": edits, "engine_restarts": studio.link.restarts - restarts0,
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
        studio.stop()
        threading.excepthook = previous_hook
        logging.getLogger().removeHandler(errors)
        shutil.rmtree(scratch, ignore_errors=True)
