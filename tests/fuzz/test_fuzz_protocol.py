"""Fuzzed engine protocol (issue 14): a malformed command becomes a Notice, never a dead engine.

The studio validates what it sends, but the engine is the last line: a command with wrong types,
NaN/inf or junk options must leave the engine running (a crash would be replayed after the restart —
a restart loop).
"""

from __future__ import annotations

import json
import os

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine import protocol as msg
from engine.core import EngineCore
from tests.conftest import REPO

pytestmark = pytest.mark.timeout(600)  # a hang is a failure too

_junk = st.one_of(st.none(), st.booleans(), st.integers(min_value=-10 ** 30, max_value=10 ** 30),
                  st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8),
                  st.lists(st.floats(allow_nan=True), max_size=4), st.dictionaries(st.text(max_size=6),
                                                                                   st.integers(), max_size=3),
                  st.sampled_from(["g1", "go2", "edit", "test", "stand", "in_place", "nosuch", "pelvis"]))
NEUTRAL = json.loads((REPO / "styles" / "g1" / "neutral.json").read_text())

_commands = st.one_of(
    st.builds(msg.SetPaused, _junk),
    st.builds(msg.ApplyPush, _junk, _junk, _junk),
    st.builds(msg.SetVelocityCommand, _junk, _junk, _junk),
    st.builds(msg.SetMode, st.sampled_from(["edit", "test", "stand"]) | _junk, _junk),
    st.builds(msg.SetMode, st.sampled_from(["edit", "test"]), st.dictionaries(st.just("sample"), _junk)),
    st.builds(msg.SetPlaybackSpeed, _junk),
    st.builds(msg.SetStyle, st.one_of(_junk, st.just(NEUTRAL)), _junk),
    st.builds(msg.StartJob, _junk, _junk),
    st.builds(msg.SwitchRobot, st.one_of(_junk.filter(lambda v: v != "go2"), st.just("../robots/g1"))),
)


@pytest.fixture(scope="module")
def core():
    events: list = []
    c = EngineCore("g1", events.append)
    c.events = events
    return c


@settings(max_examples=int(os.environ.get("FUZZ_EXAMPLES", "150")), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                   HealthCheck.too_slow])
@given(commands=st.lists(_commands, min_size=1, max_size=4))
def test_junk_commands_become_notices(core, commands):
    for command in commands:
        before = len(core.events)
        core.handle(command)  # must not raise
        for event in core.events[before:]:
            if isinstance(event, msg.Notice):
                assert "\n" not in event.message and event.message
    for _ in range(3):
        core.tick()  # the engine still steps after whatever it accepted
    core.frame()
    core.handle(msg.SetMode("stand"))
    core.handle(msg.SetVelocityCommand(0.0, 0.0, 0.0))
    core.handle(msg.SetPlaybackSpeed(1.0))
    core.handle(msg.SetPaused(False))


# ----------------------------------------------------------------------------- browser WebSocket messages

def test_junk_websocket_messages_drop_only_that_client():
    """Random bytes and malformed msgpack from one client: that client is dropped, the server and the other
    clients keep working, GUI values keep their type."""
    import random

    import msgspec
    import viser
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    from tests.conftest import free_port

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    slider = server.gui.add_slider("speed", min=0.0, max=1.0, step=0.1, initial_value=0.5)
    url = f"ws://127.0.0.1:{server.get_port()}/"
    proto = [f"viser-v{viser.__version__}"]
    rng = random.Random(14)
    payloads = [bytes(rng.randrange(256) for _ in range(rng.randrange(1, 64))) for _ in range(20)]
    payloads += [msgspec.msgpack.encode(m) for m in (
        {}, {"type": "nosuch"}, {"type": "GuiUpdateMessage"}, [1, 2, 3], "x",
        {"type": "GuiUpdateMessage", "uuid": slider._impl.uuid, "updates": {"value": "junk"}},
        {"type": "GuiUpdateMessage", "uuid": "nope", "updates": {"value": 1}},
        {"type": "ViewerCameraMessage", "wxyz": "x"},
    )]
    try:
        for payload in payloads:
            with connect(url, subprotocols=proto, open_timeout=10) as ws:
                ws.recv(timeout=10)
                try:
                    ws.send(payload)
                    ws.recv(timeout=0.5)
                except (ConnectionClosed, TimeoutError):
                    pass
        with connect(url, subprotocols=proto, open_timeout=10) as ws:  # a well-behaved client still gets the GUI
            assert ws.recv(timeout=10)
        assert server._websock_server._background_event_loop.is_running()  # noqa: SLF001
    finally:
        server.stop()
    assert slider.value == 0.5  # the junk updates did not reach the GUI state
