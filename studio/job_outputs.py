"""What a job the engine ran leaves behind when the engine dies during it (kill -9, a crash).

Every file a job writes goes through engine/atomic_io.py: a hidden temporary ``.NAME.XXXX.tmp`` beside the
output, renamed over it once complete. A kill that lands inside the write leaves the temporary (hidden, never
listed, half-written) and either the old output or none; a kill after the rename leaves the new output whole.
The panels that start jobs know each job's outputs up front (relative to the motion library) and, when the
engine is lost, call :func:`cleanup_lost_outputs` for them: temporaries removed, outputs written since the job
started reported as complete.
"""

from __future__ import annotations

from pathlib import Path


def written_since(path: Path, started_s: float) -> bool:
    """``path`` exists and was (re)written after ``started_s`` (wall clock)."""
    try:
        return path.stat().st_mtime >= started_s - 1.0
    except OSError:
        return False


def remove_temporaries(path: Path) -> list[Path]:
    """The atomic writer's temporaries of ``path`` (``.NAME.XXXX.tmp``, engine/atomic_io.py) that a killed writer
    left behind: hidden, never listed, but half-written; removed."""
    removed = []
    for tmp in path.parent.glob(f".{path.name}.*.tmp"):
        try:
            tmp.unlink()
            removed.append(tmp)
        except OSError:
            pass
    return removed


def cleanup_lost_outputs(root: Path, outputs: list[str] | tuple[str, ...], started_s: float) -> list[str]:
    """After the engine died during a job that writes ``outputs`` (relative to ``root``): remove what a cut write
    left and return the outputs that were completely written since the job started (at ``started_s``)."""
    written = [o for o in outputs if written_since(root / o, started_s)]
    for output in outputs:
        remove_temporaries(root / output)
    return written


def lost_job_text(pid: int | None, written: list[str], again: str) -> str:
    """``the engine (pid N) stopped during the job; nothing was written. Press X to start it again.``"""
    what = f"its output `{written[0]}` is complete" if written else "nothing was written"
    return f"the engine (pid {pid}) stopped during the job; {what}. {again[0].upper()}{again[1:]} to start it again."
