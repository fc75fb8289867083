"""The robot's pose stream: only moved bodies are sent, and every browser ends on each body's latest pose.

A headless viser client (the soak bench's, which decodes viser's wire format) receives the stream of a
walking-like sequence of frames; once the stream settles its last pose of every body equals the last frame
to within the view's tolerances. A hypothesis property checks the same for any sequence of small and large
moves without a client (the poses the view holds are those it sent)."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import viser
from hypothesis import given, settings
from hypothesis import strategies as st

from engine import protocol as msg
from studio.robot_view import POSITION_TOL_M, WXYZ_TOL, RobotView
from tests.conftest import free_port

BODIES = ("pelvis", "left_hip_pitch_link", "right_hip_pitch_link", "torso_link")


def _view(server: viser.ViserServer) -> RobotView:
    view = RobotView(server)
    with server.atomic():  # bare frames (no meshes): the stream is what is under test
        for name in BODIES:
            view.frames.append(server.scene.add_frame(f"/robot/{name}", show_axes=False))
    view.body_names = BODIES
    view._sent_pos = np.full((len(BODIES), 3), np.nan)
    view._sent_wxyz = np.full((len(BODIES), 4), np.nan)
    return view


def _frame(seq: int, pos: np.ndarray, wxyz: np.ndarray) -> msg.Frame:
    return msg.Frame(seq, seq / 60.0, pos.astype(np.float32), wxyz.astype(np.float32), np.zeros(0, np.float32),
                     False, False, 1.0)


def _unit(q: np.ndarray) -> np.ndarray:
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_a_headless_client_ends_on_every_bodys_latest_pose():
    from studio.bench_soak import _Client

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    stop = threading.Event()
    client = _Client(f"ws://127.0.0.1:{server.get_port()}/", stop)
    try:
        view = _view(server)
        client.start()
        deadline = time.monotonic() + 60
        while not server.get_clients() and time.monotonic() < deadline:
            time.sleep(0.05)
        rng = np.random.default_rng(3)
        pos = rng.normal(size=(len(BODIES), 3))
        wxyz = _unit(rng.normal(size=(len(BODIES), 4)))
        for seq in range(120):
            pos[:2] += 0.004  # two bodies walk; the other two stand still
            wxyz[:2] = _unit(wxyz[:2] + 0.002)
            view.update(_frame(seq, pos, wxyz))
        last = view.last_frame
        assert last is not None

        def settled() -> bool:
            for i, name in enumerate(BODIES):
                got = client.poses.get(f"/robot/{name}", {})
                if "position" not in got or "wxyz" not in got:
                    return False
                if not (np.allclose(got["position"], last.body_pos[i], atol=POSITION_TOL_M, rtol=0)
                        and np.allclose(got["wxyz"], last.body_quat[i], atol=WXYZ_TOL, rtol=0)):
                    return False
            return True

        while not settled() and time.monotonic() < deadline and not client.error:
            time.sleep(0.05)
        assert settled(), (client.error, client.poses)
        assert client.robot_frames >= 1
        # The standing bodies were sent once; the walking ones with every frame.
        assert view.poses_sent == 2 * 2 + 2 * 2 * 120
    finally:
        stop.set()
        client.join(5)
        server.stop()


def test_the_view_holds_each_bodys_last_pose_within_tolerance():
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)

    @settings(max_examples=40, deadline=None)
    @given(st.lists(st.tuples(st.integers(0, len(BODIES) - 1), st.floats(-3e-4, 3e-4), st.floats(-3e-4, 3e-4)),
                    min_size=1, max_size=40))
    def check(moves):
        view = _view(server)
        try:
            pos = np.zeros((len(BODIES), 3))
            wxyz = np.tile([1.0, 0.0, 0.0, 0.0], (len(BODIES), 1))
            for seq, (body, dp, dq) in enumerate(moves):
                pos[body] += dp
                wxyz[body] = _unit((wxyz[body] + [0.0, 0.0, 0.0, dq])[None])[0]
                view.update(_frame(seq, pos, wxyz))
                frame = view.last_frame
                for i, handle in enumerate(view.frames):  # what was sent is what the handle holds
                    assert np.abs(handle.position - frame.body_pos[i]).max() <= POSITION_TOL_M + 1e-7
                    assert np.abs(handle.wxyz - frame.body_quat[i]).max() <= WXYZ_TOL + 1e-7
        finally:
            view.clear_locked()

    try:
        check()
    finally:
        server.stop()


@pytest.mark.parametrize("n_frames", [1, 5])
def test_a_frame_that_did_not_move_sends_nothing(n_frames):
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        view = _view(server)
        pos = np.ones((len(BODIES), 3))
        wxyz = np.tile([1.0, 0.0, 0.0, 0.0], (len(BODIES), 1))
        for seq in range(n_frames):
            view.update(_frame(seq, pos, wxyz))
        assert view.poses_sent == 2 * len(BODIES) and view.frames_shown == n_frames
    finally:
        server.stop()


def test_a_loaded_robot_streams_and_tints():
    """The view of a real robot (meshes under the body frames): a frame is shown, a body recolours."""
    from engine.robot.model import load_robot

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        model = load_robot("g1")
        names = tuple(model.mj_model.body(i).name for i in range(1, model.mj_model.nbody))
        view = RobotView(server)
        view.load("g1", names)
        pos = np.arange(3 * len(names), dtype=float).reshape(-1, 3) * 0.01
        wxyz = np.tile([1.0, 0.0, 0.0, 0.0], (len(names), 1))
        view.update(_frame(0, pos, wxyz))
        assert np.allclose(view.frames[-1].position, pos[-1], atol=1e-6) and view.frames_shown == 1
        body = next(iter(view.meshes))
        view.tint(body, (230, 40, 40))
        assert tuple(view.meshes[body].color) == (230, 40, 40)
        view.tint(body, None)
        assert tuple(view.meshes[body].color) == view.base_colors[body]
    finally:
        server.stop()
