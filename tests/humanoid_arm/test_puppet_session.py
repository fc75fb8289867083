"""Live puppeteering's source handling: a flood of datagrams keeps only the newest, bad ones are counted and
named, never raised; the session retargets at its rate; the engine's puppet mode refuses bad options."""

from __future__ import annotations

import json
import socket

import numpy as np
import pytest

from engine.retarget.humanoid_arm.live import FORMAT, JOINTS
from engine.retarget.humanoid_arm.puppet_session import UdpSource, open_source


def _datagram(frame: int, lift: float) -> bytes:
    joints = {name: [0.0, 1.0, 0.0] for name in JOINTS}
    joints.update({"hips": [0, 1, 0], "right_hip": [-0.1, 1, 0], "left_hip": [0.1, 1, 0],
                   "right_shoulder": [-0.2, 1.5, 0], "left_shoulder": [0.2, 1.5, 0],
                   "right_elbow": [-0.2, 1.25, 0], "left_elbow": [0.2, 1.25, 0],
                   "right_hand": [-0.2, 1.25 + lift, 0.25], "left_hand": [0.2, 1.0, 0]})
    return json.dumps({"format": FORMAT, "frame": frame, "joints": joints}).encode()


def test_a_flood_keeps_the_newest_pose_and_bad_datagrams_are_counted():
    src = UdpSource(0)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        assert src.poll() is None  # nothing yet
        import time

        for i in range(300):  # a flood: the kernel may drop some, the source never queues them up
            tx.sendto(_datagram(i, 0.0), ("127.0.0.1", src.port))
        first = src.poll()
        assert first is not None and np.all(np.isfinite(first))
        flood_received = src.received
        assert 0 < flood_received <= 300
        tx.sendto(b'{"format": "mocap-joints/1", "joints": {"hips": [NaN, 0, 0]}}', ("127.0.0.1", src.port))
        tx.sendto(b"\xff\xfe not json", ("127.0.0.1", src.port))
        tx.sendto(_datagram(300, 0.2), ("127.0.0.1", src.port))
        deadline = time.monotonic() + 5.0
        pose = None
        while time.monotonic() < deadline and src.received < flood_received + 3:
            pose = src.poll()
        assert src.received == flood_received + 3 and src.bad == 2
        assert "datagram" in src.last_error
        assert pose is not None and np.all(np.isfinite(pose))
        # the newest valid datagram (hand lifted) is the one kept: its right forearm points up and forward
        assert pose[8] > 0.5
    finally:
        tx.close()
        src.close()


@pytest.mark.parametrize("options, message", [
    ({"source": "tcp"}, "source: expected"),
    ({"source": "udp", "port": 70000}, "port: expected"),
    ({"source": "clip", "clip": "../../etc/passwd"}, "clip: expected a .bvh file"),
])
def test_bad_puppet_options_are_one_line(options, message):
    with pytest.raises(ValueError, match=message):
        open_source(options)
