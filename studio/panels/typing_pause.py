"""A typed number field applies once the keys pause.

viser sends a number field's value on every keystroke, so typing "0.35" passes through "0" and "0.3": applying each
would make edits (and undo entries, and rehearsals) of values nobody meant. :func:`after_typing_pause` wraps a
field's callback so that it runs once, :data:`TYPING_PAUSE_S` after the last keystroke, with the last event. The
curve editor's knot fields and the Style tab's speeds use it.
"""

from __future__ import annotations

import threading
from typing import Any, Callable

TYPING_PAUSE_S = 0.4  # read at each keystroke (tests set it to 0: apply at once)


def after_typing_pause(fn: Callable[[Any], Any], ignore: Callable[[], bool] = lambda: False) -> Callable[[Any], None]:
    """A GUI ``on_update`` callback that runs ``fn(event)`` once the field's keys pause.

    ``ignore()`` true when an update arrives (the panel itself is writing the field) drops it. Each wrapped
    callback has its own timer: a keystroke in one field does not delay another.
    """
    lock = threading.Lock()
    timer: list[threading.Timer | None] = [None]

    def on_update(event: Any) -> None:
        if ignore():
            return
        pause_s = TYPING_PAUSE_S
        with lock:
            if timer[0] is not None:
                timer[0].cancel()
                timer[0] = None
            if pause_s > 0:
                pending = threading.Timer(pause_s, fn, args=(event,))
                pending.daemon = True
                timer[0] = pending
                pending.start()
                return
        fn(event)

    return on_update
