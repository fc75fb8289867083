"""The follow camera moves with the robot and keeps the user's zoom, orbit and pan (issue 16)."""

from __future__ import annotations

import contextlib
from types import SimpleNamespace

import numpy as np

from studio import camera_follow as cf
from studio.camera_follow import CameraFollow


class FakeCamera:
    """A browser camera: the studio sets it; ``report`` is the browser telling its state back."""

    def __init__(self, position, look_at):
        self.position, self.look_at = np.asarray(position, float), np.asarray(look_at, float)
        self.callbacks = []

    def __setattr__(self, name, value):
        if name == "position" and "look_at" in self.__dict__:  # viser: position moves look_at along
            self.__dict__["look_at"] = self.__dict__["look_at"] + (np.asarray(value, float) - self.position)
        object.__setattr__(self, name, np.asarray(value, float) if name in ("position", "look_at") else value)

    def on_update(self, cb):
        self.callbacks.append(cb)

    def report(self):
        for cb in self.callbacks:
            cb(self)


def _server(camera):
    client = SimpleNamespace(client_id=1, camera=camera, atomic=contextlib.nullcontext)
    return SimpleNamespace(get_clients=lambda: {1: client})


def test_following_translates_the_camera_and_keeps_the_users_zoom(monkeypatch):
    monkeypatch.setattr(cf, "USER_HOLD_S", 0.0)
    cam = FakeCamera((2.0, -2.0, 1.2), (0.0, 0.0, 0.6))
    follow = CameraFollow(_server(cam))
    assert follow.step((0.0, 0.0, 0.75), enabled=True, frozen=False) is not None
    offset = cam.position - cam.look_at
    follow.step((0.5, 0.0, 0.75), enabled=True, frozen=False)
    assert np.allclose(cam.look_at, (0.5, 0.0, 0.6)) and np.allclose(cam.position - cam.look_at, offset)
    cam.report()  # the echo of what the studio sent changes nothing
    # the user zooms in with the wheel: the browser reports a shorter offset
    cam.position = cam.look_at + 0.5 * offset
    cam.__dict__["look_at"] = np.array([0.5, 0.0, 0.6])
    cam.report()
    follow.step((1.0, 0.0, 0.75), enabled=True, frozen=False)
    assert np.allclose(cam.look_at, (1.0, 0.0, 0.6)) and np.allclose(cam.position - cam.look_at, 0.5 * offset)
    # a late echo of an earlier position does not undo the zoom
    cam.__dict__["position"] = np.array([0.5, 0.0, 0.6]) + offset
    cam.__dict__["look_at"] = np.array([0.5, 0.0, 0.6])
    cam.report()
    follow.step((1.5, 0.0, 0.75), enabled=True, frozen=False)
    assert np.allclose(cam.position - cam.look_at, 0.5 * offset)


def test_nothing_moves_while_frozen_or_disabled():
    cam = FakeCamera((2.0, -2.0, 1.2), (0.0, 0.0, 0.6))
    follow = CameraFollow(_server(cam))
    follow.step((0.0, 0.0, 0.75), enabled=True, frozen=False)
    before = cam.position.copy()
    assert follow.step((1.0, 0.0, 0.75), enabled=True, frozen=True) is None  # a knot drag
    assert follow.step((1.0, 0.0, 0.75), enabled=False, frozen=False) is None  # follow off
    assert np.allclose(cam.position, before)


def test_a_camera_placed_by_the_studio_is_followed_from_there():
    cam = FakeCamera((2.0, -2.0, 1.2), (0.0, 0.0, 0.6))
    server = _server(cam)
    follow = CameraFollow(server)
    follow.step((0.0, 0.0, 0.75), enabled=True, frozen=False)
    follow.place(server.get_clients()[1], (-1.6, -1.5, 0.6), (-1.6, 0.6, 0.6), (0.0, 0.0, 1.0))  # "to graph"
    assert np.allclose(cam.look_at, (-1.6, 0.6, 0.6)) and np.allclose(cam.up_direction, (0.0, 0.0, 1.0))
    follow.step((0.3, 0.0, 0.75), enabled=True, frozen=False)
    assert np.allclose(cam.look_at, (-1.3, 0.6, 0.6)) and np.allclose(cam.position, (-1.3, -1.5, 0.6))


def test_a_follow_step_on_another_thread_cannot_undo_a_placed_camera():
    """The drive panel's thread steps the follow while a button's thread points the camera at the graph: the step
    waits for the placement and then follows from the graph (it used to overwrite the new camera with the old follow
    pose in between, and that pose was adopted as the place to follow)."""
    import threading

    cam = FakeCamera((2.0, -2.0, 1.2), (0.0, 0.0, 0.6))
    server = _server(cam)
    follow = CameraFollow(server)
    follow.step((0.0, 0.0, 0.75), enabled=True, frozen=False)
    stepper: list[threading.Thread] = []

    def step_meanwhile(value) -> None:  # the robot walks on while the placement is half written
        if not stepper:
            stepper.append(threading.Thread(target=follow.step, args=((0.3, 0.0, 0.75), True, False)))
            stepper[0].start()
            stepper[0].join(0.2)

    original = FakeCamera.__setattr__

    def setattr_with_step(self, name, value):
        if name == "position":
            step_meanwhile(value)
        original(self, name, value)

    FakeCamera.__setattr__ = setattr_with_step
    try:
        follow.place(server.get_clients()[1], (-1.6, -1.5, 0.6), (-1.6, 0.6, 0.6))
    finally:
        FakeCamera.__setattr__ = original
    stepper[0].join(2.0)
    assert not stepper[0].is_alive()
    # following from the graph (y 0.6), not from the old follow pose (y 0): the step came after the placement
    assert np.allclose(cam.look_at, (-1.3, 0.6, 0.6)) and np.allclose(cam.position, (-1.3, -1.5, 0.6))


def test_a_late_echo_from_seconds_ago_is_not_taken_for_the_users_move(monkeypatch):
    """A slow tab reports cameras the studio sent seconds earlier (hundreds of sends back): still an echo."""
    monkeypatch.setattr(cf, "USER_HOLD_S", 0.0)
    cam = FakeCamera((2.0, -2.0, 1.2), (0.0, 0.0, 0.6))
    follow = CameraFollow(_server(cam))
    for k in range(301):  # 5 s at 60 Hz, 5 mm a frame (a robot at 0.3 m/s)
        follow.step((0.005 * k, 0.0, 0.75), enabled=True, frozen=False)
    offset = cam.position - cam.look_at
    cam.__dict__["look_at"] = np.array([0.01, 0.0, 0.6])  # what the tab shows now: the camera of 5 s ago
    cam.__dict__["position"] = cam.look_at + offset
    cam.report()
    follow.step((1.51, 0.0, 0.75), enabled=True, frozen=False)
    assert np.allclose(cam.look_at, (1.51, 0.0, 0.6))  # still following the robot, not held 1.5 m behind it


def test_the_sent_history_forgets_after_its_window():
    history = cf._SentHistory()
    history.append(np.array([0.0, 0.0, 0.6]), now_s=100.0)
    history.append(np.array([1.0, 0.0, 0.6]), now_s=100.0 + cf.ECHO_WINDOW_S / 2)
    now = 100.0 + cf.ECHO_WINDOW_S / 2
    assert history.near(np.array([0.001, 0.0, 0.6]), now_s=now) and not history.near(np.array([0.5, 0.0, 0.6]), now_s=now)
    assert history.near(np.array([0.5, 0.0, 0.6]), np.array([0.5, 0.0, 0.6]), now_s=now)  # an extra candidate counts
    later = 100.0 + cf.ECHO_WINDOW_S + 1.0
    assert not history.near(np.array([0.0, 0.0, 0.6]), now_s=later)  # forgotten without a new send
    assert history.near(np.array([1.0, 0.0, 0.6]), now_s=later)
    history.append(np.array([2.0, 0.0, 0.6]), now_s=later)
    assert len(history) == 2 and not history.near(np.array([0.0, 0.0, 0.6]), now_s=later)
    assert np.allclose(history[-1], (2.0, 0.0, 0.6))
