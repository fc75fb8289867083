"""The engine's outbox: puts never wait for the studio, frames and telemetry are latest-wins, the rest is delivered in order."""

from __future__ import annotations

import socket
import threading
from multiprocessing.connection import Connection

import numpy as np
import pytest

from engine import protocol as msg
from engine.outbox import Outbox


def _pair() -> tuple[Connection, Connection]:
    a, b = socket.socketpair()
    return Connection(a.detach()), Connection(b.detach())


def _frame(seq: int, joint_q: np.ndarray | None = None) -> msg.Frame:
    return msg.Frame(seq=seq, sim_time_s=seq * 0.002, body_pos=np.zeros((3, 3), np.float32),
                     body_quat=np.zeros((3, 4), np.float32),
                     joint_q=np.zeros(29, np.float32) if joint_q is None else joint_q, paused=False, fallen=False,
                     real_time_factor=1.0, mode="test", style_revision=0)


def _read_all(reader: Connection) -> list[msg.Event]:
    events = []
    while reader.poll(0.5):
        events.append(reader.recv())
    return events


def test_a_reader_that_does_not_read_never_blocks_the_engine_and_misses_only_stale_frames():
    engine_side, studio_side = _pair()
    outbox = Outbox(engine_side)
    done = threading.Event()

    def engine() -> None:  # 3000 frames of ~1.6 kB: far more than the socket's buffer holds
        for seq in range(3000):
            outbox.put(_frame(seq))
            if seq % 500 == 0:
                outbox.put(msg.Notice("info", f"notice {seq}"))
        done.set()

    thread = threading.Thread(target=engine, daemon=True)
    thread.start()
    assert done.wait(60), "put() waited for the reader (with a blocking send the engine would stop here)"
    assert outbox.pending() <= 7  # the socket is full: one message in flight, one frame and the last 5 notices pending
    events = _read_all(studio_side)
    outbox.close()
    frames = [e for e in events if isinstance(e, msg.Frame)]
    notices = [e.message for e in events if isinstance(e, msg.Notice)]
    assert notices == [f"notice {seq}" for seq in range(0, 3000, 500)]  # every other event, in order
    assert frames[-1].seq == 2999  # the newest state arrives
    assert len(frames) < 3000 and outbox.replaced == 3000 - len(frames)
    assert [f.seq for f in frames] == sorted(f.seq for f in frames)


def test_a_frame_never_overtakes_an_event_put_after_it():
    engine_side, studio_side = _pair()
    outbox = Outbox(engine_side)
    for seq in range(200):  # the robot switches at 100: no frame of the old robot may follow its announcement
        if seq == 100:
            outbox.put(msg.Notice("info", "switched"))
        outbox.put(_frame(seq))
    events = _read_all(studio_side)
    outbox.close()
    at = next(i for i, e in enumerate(events) if isinstance(e, msg.Notice))
    assert all(e.seq < 100 for e in events[:at] if isinstance(e, msg.Frame))
    assert all(e.seq >= 100 for e in events[at:] if isinstance(e, msg.Frame))
    assert isinstance(events[-1], msg.Frame) and events[-1].seq == 199


def test_what_is_sent_is_the_state_when_it_was_put():
    engine_side, studio_side = _pair()
    outbox = Outbox(engine_side)
    q = np.arange(29, dtype=np.float32)
    outbox.put(_frame(0, joint_q=q))  # a state the engine keeps writing into after put
    q[:] = -1.0
    (event,) = _read_all(studio_side)
    outbox.close()
    np.testing.assert_array_equal(event.joint_q, np.arange(29, dtype=np.float32))


def test_a_studio_gone_away_ends_the_engine_loop():
    engine_side, studio_side = _pair()
    outbox = Outbox(engine_side)
    studio_side.close()
    with pytest.raises(BrokenPipeError):
        for seq in range(10_000):  # the sender meets the closed socket; a later put reports it
            outbox.put(msg.Notice("info", f"{seq}"))
            outbox._thread.join(0.001)
    outbox.close()


def test_close_sends_what_is_pending():
    engine_side, studio_side = _pair()
    outbox = Outbox(engine_side)
    outbox.put(msg.Notice("error", "engine could not load 'nope'"))
    outbox.close()
    assert [e.message for e in _read_all(studio_side)] == ["engine could not load 'nope'"]
