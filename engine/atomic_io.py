"""Atomic file writes: a temporary file next to the target, flushed, then renamed over it.

A crash or a full disk never leaves a half-written style, motion, cache or recording behind.

Fault injection, for tests only: with ``MOTION_STUDIO_TEST_HOLD_WRITES`` set to a file-name pattern (fnmatch,
e.g. ``*.csv``), a write of a matching file stops after its temporary is written and flushed, before the rename,
for ``MOTION_STUDIO_TEST_HOLD_SECONDS`` (default 120) — so that a test can kill -9 the process while it is
certainly inside the write (tests/test_faults.py). Unset (always, outside those tests), nothing changes.
"""

from __future__ import annotations

import fnmatch
import os
import tempfile
import time
from pathlib import Path

HOLD_WRITES_ENV = "MOTION_STUDIO_TEST_HOLD_WRITES"
HOLD_SECONDS_ENV = "MOTION_STUDIO_TEST_HOLD_SECONDS"


def _hold_for_tests(path: Path) -> None:
    """The fault-injection hook (see the module docstring): a no-op unless the test-only variable is set."""
    pattern = os.environ.get(HOLD_WRITES_ENV)
    if pattern and fnmatch.fnmatch(path.name, pattern):
        time.sleep(float(os.environ.get(HOLD_SECONDS_ENV) or 120.0))


def _umask() -> int:
    """The process umask, read without changing it where Linux allows (os.umask both reads and sets)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically. The file keeps the mode of the file it replaces; a new file
    gets 0666 minus the umask, as ``open()`` would give it (not mkstemp's private 0600)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        mode = path.stat().st_mode & 0o7777
    except OSError:
        mode = 0o666 & ~_umask()
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            _hold_for_tests(path)
            os.fchmod(f.fileno(), mode)
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))
