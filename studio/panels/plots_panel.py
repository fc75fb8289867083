"""Plots (paper Figs. 13–14): sample activation, gait feedback and reference-vs-achieved tracking."""

from __future__ import annotations

import threading
from collections import deque

import numpy as np
import viser
from viser.uplot import Scale

from engine.gait.velocity_sampler import SAMPLE_DISPLAY_NAMES

WINDOW_S = 10.0
PLOTTED = ("sample_weights", "feedback", "recovery_share", "pelvis_z", "pelvis_yaw", "arm_joint")  # the signals the plots draw
MAX_POINTS = 120  # per series sent to the browser
SCALES: dict[str, Scale] = {"x": {"time": False, "auto": True}, "y": {"auto": True}}


def time_window_scales(t_now_s: float) -> dict:
    """uPlot scales with the time axis pinned to the last :data:`WINDOW_S` of engine time.

    viser's chart keeps the x range it had when first drawn (e.g. 4–12 s while the engine is at 50 s,
    or a range before any curve: empty plots); an explicit range sent with every update (a new chart
    for the browser, pinned at creation) follows the engine clock."""
    return {"x": {"time": False, "auto": False, "range": (round(t_now_s - WINDOW_S, 3), round(t_now_s, 3))},
            "y": {"auto": True}}
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22")


def _series(labels: tuple[str, ...], colors: tuple[str, ...]) -> tuple:
    return ({"label": "t (s)"}, *({"label": l, "stroke": c, "width": 1.5} for l, c in zip(labels, colors)))


class PlotsPanel:
    def __init__(self, server: viser.ViserServer):
        self.server = server
        self.buffer: deque[tuple[float, dict[str, np.ndarray]]] = deque()
        self._lock = threading.Lock()
        empty = np.zeros(2)
        self.weights = server.gui.add_uplot((empty, *([empty] * 9)), _series(SAMPLE_DISPLAY_NAMES, PALETTE),
                                            title="Sample activation", aspect=1.6, scales=SCALES)
        # with the balance recovery's share of the neutral gait (engine/control/recovery_blend.py): while it is
        # above 0 the robot walks part neutral, not the style as authored
        self.feedback = server.gui.add_uplot((empty, empty, empty, empty, empty),
                                             _series(("Δvel x (m/s)", "Δstep x (m)", "κ − 1", "neutral share"),
                                                     PALETTE[:4]),
                                             title="Gait feedback", aspect=1.6, scales=SCALES)
        self.tracking = server.gui.add_uplot(
            (empty, *([empty] * 6)),
            _series(("pelvis z ref", "pelvis z", "yaw ref", "yaw", "arm ref", "arm"),
                    ("#1f77b4", "#9ecae1", "#ff7f0e", "#fdae6b", "#2ca02c", "#a1d99b")),
            title="Tracking: reference vs achieved", aspect=1.6, scales=SCALES)

    def add(self, t_s: float, signals: dict[str, np.ndarray]) -> None:
        """Telemetry from the engine (its own thread): kept for the last :data:`WINDOW_S` of engine time."""
        if "sample_weights" not in signals:
            return
        # Only what the plots draw, not the paths and footholds: 10 s of sim time is 200 packets at real time,
        # 2000 (3 kB pickled each with every signal, 0.4 kB kept) when the engine runs at a tenth of it.
        kept = {k: signals[k] for k in PLOTTED if k in signals}
        with self._lock:
            self.buffer.append((float(t_s), kept))
            while self.buffer and (t_s - self.buffer[0][0] > WINDOW_S or self.buffer[0][0] > t_s):
                self.buffer.popleft()  # older than the window, or from before a reset

    def render(self) -> None:
        """Send the window to the browser (status thread). The buffer is copied under the lock: iterating
        it while telemetry arrives raised "deque mutated during iteration", so the plots never updated."""
        with self._lock:
            items = list(self.buffer)
        if len(items) < 2:
            return
        if len(items) > MAX_POINTS:  # fewer points: less to send and to draw under software WebGL
            items = [items[i] for i in np.linspace(0, len(items) - 1, MAX_POINTS).round().astype(int)]
        t = np.array([b[0] for b in items])
        w = np.array([b[1]["sample_weights"] for b in items], dtype=float)
        fb = np.array([b[1].get("feedback", np.array([0, 0, 0, 0, 1.0])) for b in items], dtype=float)
        pz = np.array([b[1]["pelvis_z"] for b in items], dtype=float)
        yaw = np.array([b[1]["pelvis_yaw"] for b in items], dtype=float)
        arm = np.array([b[1].get("arm_joint", np.zeros(2)) for b in items], dtype=float)
        share = np.array([float(b[1].get("recovery_share", np.zeros(1))[0]) for b in items])
        yaw = np.unwrap(yaw, axis=0)
        scales = time_window_scales(float(t[-1]))
        for plot, data in ((self.weights, (t, *w.T)), (self.feedback, (t, fb[:, 0], fb[:, 2], fb[:, 4] - 1.0, share)),
                           (self.tracking, (t, pz[:, 0], pz[:, 1], yaw[:, 0], yaw[:, 1], arm[:, 0], arm[:, 1]))):
            plot.data = data
            plot.scales = scales
