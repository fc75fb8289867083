"""The engine's outgoing events, written to the studio by their own thread: the simulation never waits for a reader.

The engine paces its simulation to the wall clock. When the studio reads slowly (a browser rendering with
software WebGL on the same two cores starves it), a blocking write on the socket stops the simulation until
the studio catches up: with the socket's buffer full (212 kB, about a second of frames and telemetry), the
engine spent 10-30 % of its wall time inside ``send`` and the robot walked in slow motion.

Frames and telemetry are states: only the newest matters, so a pending one is replaced by its successor
(``latest wins``, in the order of the newest), and what a slow studio misses it never needed. Every other
event (robot loaded, notices, job progress and results) is delivered, in order. Events are serialised when
they are put, in the engine's thread, so what is sent is the state of that moment even if the engine reuses
its arrays afterwards.
"""

from __future__ import annotations

import threading
from collections import deque
from multiprocessing.connection import Connection
from multiprocessing.reduction import ForkingPickler

from engine import protocol as msg

#: Event kinds of which only the newest pending one is sent.
LATEST_WINS_KINDS = frozenset({"frame", "telemetry"})


class Outbox:
    """Serialise events now, send them from a thread; frames and telemetry are latest-wins while pending."""

    def __init__(self, conn: Connection):
        self._conn = conn
        self._cond = threading.Condition()
        self._pending: deque[tuple[str, bytes]] = deque()
        self._closing = False
        self._sending = False
        self.error: BaseException | None = None  # the socket's failure (the studio went away), raised by put()
        self.replaced = 0  # frames and telemetry replaced before they were sent (the studio was behind)
        self._thread = threading.Thread(target=self._run, name="engine-outbox", daemon=True)
        self._thread.start()

    def put(self, event: msg.Event) -> None:
        """Queue ``event``; raises the socket's error once the sender has met one (EOF, broken pipe)."""
        if self.error is not None:
            raise BrokenPipeError(f"the studio's socket failed: {self.error}") from self.error
        kind = event.kind
        payload = bytes(ForkingPickler.dumps(event))  # Connection.send's own serialisation, read by recv()
        with self._cond:
            if kind in LATEST_WINS_KINDS:
                for i, (pending_kind, _) in enumerate(self._pending):
                    if pending_kind == kind:
                        del self._pending[i]
                        self.replaced += 1
                        break
            self._pending.append((kind, payload))
            self._cond.notify()

    def pending(self) -> int:
        with self._cond:
            return len(self._pending) + (1 if self._sending else 0)

    def close(self, timeout_s: float = 1.0) -> None:
        """Send what is pending (for at most ``timeout_s``), then stop the thread."""
        with self._cond:
            self._closing = True
            self._cond.notify()
        self._thread.join(timeout_s)

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._pending and not self._closing:
                    self._cond.wait()
                if not self._pending:
                    return  # closing, everything sent
                _, payload = self._pending.popleft()
                self._sending = True
            try:
                self._conn.send_bytes(payload)
            except (OSError, EOFError) as exc:  # the studio went away: the engine's loop ends on its next put
                with self._cond:
                    self.error = exc
                    self._pending.clear()
                    self._sending = False
                return
            with self._cond:
                self._sending = False
