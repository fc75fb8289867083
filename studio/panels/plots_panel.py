"""Plots (paper Figs. 13–14): sample activation, gait feedback and reference-vs-achieved tracking."""

from __future__ import annotations

from collections import deque

import numpy as np
import viser

from engine.gait.velocity_sampler import SAMPLE_DISPLAY_NAMES

WINDOW_S = 10.0
SCALES = {"x": {"time": False, "auto": True}, "y": {"auto": True}}
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22")


def _series(labels: tuple[str, ...], colors: tuple[str, ...]) -> tuple:
    return ({"label": "t (s)"}, *({"label": l, "stroke": c, "width": 1.5} for l, c in zip(labels, colors)))


class PlotsPanel:
    def __init__(self, server: viser.ViserServer):
        self.server = server
        self.buffer: deque[tuple[float, dict[str, np.ndarray]]] = deque()
        empty = np.zeros(2)
        self.weights = server.gui.add_uplot((empty, *([empty] * 9)), _series(SAMPLE_DISPLAY_NAMES, PALETTE),
                                            title="Sample activation", aspect=1.6, scales=SCALES)
        self.feedback = server.gui.add_uplot((empty, empty, empty, empty),
                                             _series(("Δvel x (m/s)", "Δstep x (m)", "κ − 1"), PALETTE[:3]),
                                             title="Gait feedback", aspect=1.6, scales=SCALES)
        self.tracking = server.gui.add_uplot(
            (empty, *([empty] * 6)),
            _series(("pelvis z ref", "pelvis z", "yaw ref", "yaw", "arm ref", "arm"),
                    ("#1f77b4", "#9ecae1", "#ff7f0e", "#fdae6b", "#2ca02c", "#a1d99b")),
            title="Tracking: reference vs achieved", aspect=1.6, scales=SCALES)

    def add(self, t_s: float, signals: dict[str, np.ndarray]) -> None:
        if "sample_weights" not in signals:
            return
        self.buffer.append((t_s, signals))
        while self.buffer and (t_s - self.buffer[0][0] > WINDOW_S or self.buffer[0][0] > t_s):
            self.buffer.popleft()

    def render(self) -> None:
        if len(self.buffer) < 2:
            return
        t = np.array([b[0] for b in self.buffer])
        w = np.array([b[1]["sample_weights"] for b in self.buffer])
        fb = np.array([b[1].get("feedback", np.array([0, 0, 0, 0, 1.0])) for b in self.buffer])
        pz = np.array([b[1]["pelvis_z"] for b in self.buffer])
        yaw = np.array([b[1]["pelvis_yaw"] for b in self.buffer])
        arm = np.array([b[1].get("arm_joint", np.zeros(2)) for b in self.buffer])
        yaw = np.unwrap(yaw, axis=0)
        self.weights.data = (t, *w.T)
        self.feedback.data = (t, fb[:, 0], fb[:, 2], fb[:, 4] - 1.0)
        self.tracking.data = (t, pz[:, 0], pz[:, 1], yaw[:, 0], yaw[:, 1], arm[:, 0], arm[:, 1])
