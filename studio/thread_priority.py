"""The simulation before the streaming: the studio's streaming threads yield the CPU to the engine process.

On a machine short of CPU (two cores, a browser rendering beside the studio) the engine, the studio's
WebSocket event loop, its joystick/camera thread and the browser share the cores. When the engine does
not get its share it lets simulated time fall behind (``studio bench soak``'s drift); when the streaming
threads do not, the browsers get fewer frames, which the stream rate already absorbs. So those threads
run at a higher niceness than the engine (Linux: a thread's niceness is its own; raising it needs no
privilege). The engine-link thread stays as it is: the engine process is started from it and inherits
its niceness.
"""

from __future__ import annotations

from engine.scheduling import lower_thread_priority

STREAMING_NICENESS = 5  # added to the studio's own niceness for its streaming threads


def yield_to_engine(niceness: int = STREAMING_NICENESS) -> None:
    """Raise the calling thread's niceness by ``niceness`` (a no-op where threads have no niceness of their own)."""
    lower_thread_priority(niceness)
