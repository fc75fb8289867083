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
    follow = CameraFollow(_server(cam))
    follow.step((0.0, 0.0, 0.75), enabled=True, frozen=False)
    cam.position, cam.__dict__["look_at"] = np.array([-1.6, -1.5, 0.6]), np.array([-1.6, 0.6, 0.6])  # "to graph"
    follow.adopt(SimpleNamespace(client_id=1, camera=cam))
    follow.step((0.3, 0.0, 0.75), enabled=True, frozen=False)
    assert np.allclose(cam.look_at, (-1.3, 0.6, 0.6)) and np.allclose(cam.position, (-1.3, -1.5, 0.6))
