"""``studio bench edit``: edit-to-robot latency through the studio's real path.

A curve edit arriving at the server (:meth:`StyleSession.apply`) until the first streamed pose
computed with it (engine process in edit mode, real pipe, real pacing). It lives in the studio
because it drives the studio's own session and engine link; the engine never imports the studio.
"""

from __future__ import annotations

import time
from pathlib import Path

from engine.bench.stats import percentiles_us


def bench_edit_latency(edits: int = 20) -> list[dict]:
    """Median and p99 of the edit-to-robot latency over ``edits`` curve edits (G1, in-place sample)."""
    import threading

    from engine import protocol as msg
    from engine.gait.curves import HermiteCurve, Knot, TangentMode
    from studio.engine_link import EngineLink
    from studio.style_session import StyleSession

    seen: dict[int, float] = {}
    loaded = threading.Event()
    lock = threading.Lock()

    def on_event(event) -> None:
        if isinstance(event, msg.RobotLoaded):
            loaded.set()
        elif isinstance(event, msg.Frame):
            with lock:
                if event.style_revision not in seen:
                    seen[event.style_revision] = time.perf_counter()

    import shutil
    import tempfile

    from engine.gait.style import styles_dir

    scratch = Path(tempfile.mkdtemp(prefix="motion-studio-bench-"))
    shutil.copy(styles_dir("g1") / "neutral.json", scratch / "neutral.json")
    link = EngineLink("g1", on_event)
    link.start()
    session = StyleSession("g1", folder=scratch)  # never autosave into the user's styles
    session.open("neutral")
    sent: dict[int, float] = {}
    revision = [0]

    def push(style, reason) -> None:
        revision[0] += 1
        sent[revision[0]] = time.perf_counter()
        link.send(msg.SetStyle(session.as_document(), revision=revision[0]))

    session.subscribe(push, urgent=True)  # as the studio's engine link
    try:
        if not loaded.wait(60):
            raise RuntimeError("engine did not start")
        link.send(msg.SetMode("edit", {"sample": "in_place"}))
        time.sleep(2.0)
        for i in range(edits):
            style = session.style
            assert style is not None  # opened above
            sample = style.samples["in_place"]
            curve = sample.curves["left_foot.z"]
            d = curve.duration_s
            height = 0.05 + 0.02 * (i % 2)
            new = HermiteCurve([Knot(0.0, 0.0, mode=TangentMode.FLAT), Knot(0.5 * d, height),
                                Knot(d, 0.0, mode=TangentMode.FLAT)], d)
            t0 = time.perf_counter()
            session.apply(style.with_sample("in_place", sample.with_curve("left_foot.z", new)), "bench")
            sent[revision[0]] = t0  # the edit arrived at the server when apply() was called
            time.sleep(0.25)
    finally:
        link.stop()
        shutil.rmtree(scratch, ignore_errors=True)
    latencies = [seen[r] - sent[r] for r in sent if r in seen and seen[r] >= sent[r]]
    row = {"section": "edit", "robot": "g1", "edits": len(sent), "reflected": len(latencies), **percentiles_us(latencies),
           "goal_median_us": 100_000}
    return [row]
