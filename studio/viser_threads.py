"""Pushing viser messages from the studio's threads without touching asyncio's waiters off the event loop.

The studio queues scene and GUI messages from its own threads (the engine link's frames and telemetry, the
joystick and camera follow, viser's thread-pool callbacks). viser 1.1.1's ``AsyncMessageBuffer.push`` raises
its ``asyncio.Event`` directly from the calling thread (so the flag reads set at once), and
``asyncio.Event.set`` iterates the deque of waiting futures — which the event loop's thread appends to and
removes from as the connections' window generators park and wake. When a thread pushes the second message of
an atomic block while the loop is waking the generators the first one woke, the deque changes under the
iteration: ``RuntimeError: deque mutated during iteration``, raised in the pushing thread (the soak saw it
as "studio failed to show telemetry"). It also resolves the futures from the wrong thread.

:func:`allow_pushes_from_threads` gives every message buffer of viser an event whose ``set`` from any other
thread only raises the flag; waking the waiters stays on the loop, where viser already schedules it for
every push (``call_soon_threadsafe(message_event.set)``, or once at the end of an atomic block). Nothing else
of viser changes; on another viser layout it does nothing (the setting in pyproject.toml keeps viser < 1.2).
"""

from __future__ import annotations

import asyncio
import asyncio.events
import functools
from typing import Any

_INSTALLED = "_motion_studio_loop_safe"


class LoopSafeEvent(asyncio.Event):
    """An ``asyncio.Event`` that only its own event loop's thread wakes: ``set`` from another thread raises the
    flag (``is_set()`` and a later ``wait()`` see it at once) and leaves the parked waiters to the loop's own
    ``set``, which wakes them whether or not the flag was already raised."""

    owner_loop: asyncio.AbstractEventLoop | None = None

    def set(self) -> None:
        running = asyncio.events._get_running_loop()
        on_loop = running is not None and (self.owner_loop is None or running is self.owner_loop)
        if not on_loop:
            self._value = True
            return
        self._value = True
        for waiter in self._waiters:  # on the loop's thread: nothing mutates it now
            if not waiter.done():
                waiter.set_result(True)


def _make_loop_safe(buffer: Any) -> None:
    event = getattr(buffer, "message_event", None)
    if type(event) is asyncio.Event:
        event.__class__ = LoopSafeEvent  # same layout: waiters already parked stay parked
    if isinstance(event, LoopSafeEvent):
        event.owner_loop = getattr(buffer, "event_loop", None)


def allow_pushes_from_threads(server: Any) -> bool:
    """Make pushes to ``server``'s message buffers (and to every buffer viser creates from now on, e.g. for
    each new connection) safe from any thread. Returns False if this viser has another layout (nothing done)."""
    try:
        from viser.infra._async_message_buffer import AsyncMessageBuffer
    except ImportError:
        return False
    if not hasattr(AsyncMessageBuffer, "push") or "message_event" not in getattr(AsyncMessageBuffer,
                                                                                  "__dataclass_fields__", {}):
        return False
    if not getattr(AsyncMessageBuffer, _INSTALLED, False):
        original_init = AsyncMessageBuffer.__init__

        @functools.wraps(original_init)
        def init(self: Any, *args: Any, **kwargs: Any) -> None:
            original_init(self, *args, **kwargs)
            _make_loop_safe(self)

        AsyncMessageBuffer.__init__ = init  # type: ignore[method-assign]
        setattr(AsyncMessageBuffer, _INSTALLED, True)
    websock = getattr(server, "_websock_server", None)
    buffers = [getattr(websock, "_broadcast_buffer", None)]
    buffers += [getattr(state, "message_buffer", None) for state in
                list(getattr(websock, "_client_state_from_id", {}).values())]
    for buffer in buffers:
        if buffer is not None:
            _make_loop_safe(buffer)
    return True
