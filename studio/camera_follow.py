"""The follow camera: it moves with the walking robot and keeps what the animator chose.

Every browser's camera keeps, relative to the robot, the point it looks at (``look_rel``: horizontal
offset, absolute height) and its own offset from that point (``offset``: orbit and zoom distance).
Following only translates the camera by the robot's motion, so the mouse wheel, an orbit or a pan
made while following stays: a camera report from the browser that is not the echo of a position the
studio sent is the user's, and is adopted. The curve graph travels with the camera (same translation,
so it stays put on screen); nothing moves while a knot is being dragged.
"""

from __future__ import annotations

import collections
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

LOOK_HEIGHT_M = 0.6
ECHO_TOL_M = 5e-3  # a reported camera this close to one the studio sent is that send's echo
USER_HOLD_S = 0.6  # after the user moves the camera, following waits this long (the gesture may go on)
MIN_STEP_M = 2e-3  # smaller robot motions are not sent
#: A browser's camera reports can trail what the studio sent by seconds (a software-WebGL tab on a slow, loaded
#: machine): every send of this long ago still counts for recognising its echo. Counted by sends (60 of them, one
#: second at 60 Hz) a late echo of a walking robot's camera was taken for the user's own move and adopted,
#: and the camera went back where it had been (the e2e test's "camera on the graph" timed out once in CI).
ECHO_WINDOW_S = 10.0


def _write_camera(client: Any, position: np.ndarray, look_at: np.ndarray,
                  up_direction: np.ndarray | tuple[float, float, float] | None = None) -> None:
    """Send ``client`` one camera pose (one atomic block); the caller holds the follow's lock."""
    cam = client.camera
    with client.atomic():
        if up_direction is not None:
            cam.up_direction = tuple(up_direction)
        cam.position = tuple(position)  # translates look_at too …
        cam.look_at = tuple(look_at)  # … then pin it exactly


class _SentHistory:
    """Vectors the studio sent, kept ``ECHO_WINDOW_S``; is a reported vector one of them (within ``ECHO_TOL_M``)?"""

    def __init__(self) -> None:
        self._times: collections.deque[float] = collections.deque()
        self._vectors: collections.deque[np.ndarray] = collections.deque()
        self._stacked: np.ndarray | None = None

    def append(self, vector: np.ndarray, now_s: float | None = None) -> None:
        now = time.monotonic() if now_s is None else now_s
        self._times.append(now)
        self._vectors.append(np.asarray(vector, float).copy())
        self._stacked = None
        self._forget(now)

    def _forget(self, now_s: float) -> None:
        while self._times and self._times[0] < now_s - ECHO_WINDOW_S:
            self._times.popleft()
            self._vectors.popleft()
            self._stacked = None

    def near(self, vector: np.ndarray, *others: np.ndarray, now_s: float | None = None) -> bool:
        self._forget(time.monotonic() if now_s is None else now_s)
        if self._vectors and self._stacked is None:
            self._stacked = np.array(self._vectors)
        rows = [self._stacked] if self._stacked is not None else []
        rows += [np.asarray(o, float)[None, :] for o in others]
        if not rows:
            return False
        return bool(np.min(np.linalg.norm(np.concatenate(rows) - vector, axis=1)) < ECHO_TOL_M)

    def __len__(self) -> int:
        return len(self._vectors)

    def __getitem__(self, index: int) -> np.ndarray:
        return self._vectors[index]


@dataclass
class _ClientFollow:
    look_rel: np.ndarray  # look-at point minus the robot's ground position (z: absolute height)
    offset: np.ndarray | None = None  # camera position minus look-at (None: take the browser's)
    sent_looks: _SentHistory = field(default_factory=_SentHistory)
    sent_offsets: _SentHistory = field(default_factory=_SentHistory)
    user_until: float = 0.0
    robot: np.ndarray = field(default_factory=lambda: np.zeros(3))


class CameraFollow:
    def __init__(self, server: Any):
        self.server = server
        self._lock = threading.Lock()
        self._state: dict[int, _ClientFollow] = {}
        self._registered: set[int] = set()
        self.robot_ground = np.zeros(3)

    @staticmethod
    def _ground(position) -> np.ndarray:
        return np.array([float(position[0]), float(position[1]), 0.0])

    def recentre(self) -> None:
        """Next step looks at the robot again (follow switched on, mode changed); zoom and orbit stay."""
        with self._lock:
            for st in self._state.values():
                st.look_rel = np.array([0.0, 0.0, LOOK_HEIGHT_M])
                st.user_until = 0.0

    def place(self, client: Any, position: np.ndarray | tuple[float, float, float],
              look_at: np.ndarray | tuple[float, float, float],
              up_direction: np.ndarray | tuple[float, float, float] | None = None) -> None:
        """The studio itself points ``client``'s camera (e.g. "Camera to graph") and following goes on from there.

        One step under the follow's lock: a follow step on the drive panel's thread can neither overwrite the new
        camera with the old follow pose in between, nor have that overwrite adopted as the place to follow."""
        look, pos = np.asarray(look_at, float), np.asarray(position, float)
        with self._lock:
            _write_camera(client, pos, look, up_direction)
            st = self._state.setdefault(client.client_id, _ClientFollow(np.array([0.0, 0.0, LOOK_HEIGHT_M])))
            st.look_rel = look - self.robot_ground
            st.offset = pos - look
            st.sent_looks.append(look)
            st.sent_offsets.append(pos - look)
            st.user_until = 0.0

    def _on_camera(self, client: Any) -> None:
        """A camera report from the browser: an echo of ours, or the user's own move (adopted)."""
        cam = client.camera
        with self._lock:
            st = self._state.get(client.client_id)
            if st is None:
                return
            look, pos = np.asarray(cam.look_at, float), np.asarray(cam.position, float)
            offset = pos - look
            user = False
            if st.offset is not None and not st.sent_offsets.near(offset, st.offset):
                st.offset = offset
                user = True
            if len(st.sent_looks) and not st.sent_looks.near(look):
                st.look_rel = look - self.robot_ground
                user = True
            if user:
                st.user_until = time.monotonic() + USER_HOLD_S

    def step(self, robot_position, enabled: bool, frozen: bool) -> np.ndarray | None:
        """Move every browser's camera with the robot; returns the robot's ground position followed
        (None when nothing follows: disabled, or ``frozen`` during a drag)."""
        ground = self._ground(robot_position)
        with self._lock:  # a place() in progress measures the look from the ground it started with
            self.robot_ground = ground
        if not enabled or frozen:
            return None
        now = time.monotonic()
        for client in list(self.server.get_clients().values()):
            cid = client.client_id
            if cid not in self._registered:
                self._registered.add(cid)
                client.camera.on_update(lambda cam, c=client: self._on_camera(c))
            try:
                cam = client.camera
                look_now, pos_now = np.asarray(cam.look_at, float), np.asarray(cam.position, float)
            except AssertionError:  # no camera report from this browser yet
                continue
            with self._lock:
                st = self._state.setdefault(cid, _ClientFollow(np.array([0.0, 0.0, LOOK_HEIGHT_M])))
                if now < st.user_until:
                    continue
                if st.offset is None:
                    st.offset = pos_now - look_now
                look = ground + st.look_rel
                if (float(np.linalg.norm(look - look_now)) < MIN_STEP_M
                        and float(np.linalg.norm(pos_now - look_now - st.offset)) < ECHO_TOL_M):
                    continue
                position = look + st.offset
                st.sent_looks.append(look, now)
                st.sent_offsets.append(st.offset, now)
                _write_camera(client, position, look)  # under the lock: a place() cannot land in between
        return ground
