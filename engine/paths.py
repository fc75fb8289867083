"""Names typed or picked by a user stay inside their folder.

``confined(folder, name, suffix)`` is the one gate for every file picker and every typed name (style
open / save / save as / new / recover, and the motion and retargeting pickers that follow): it
refuses ``../``, absolute paths, path separators, hidden names and symlinks whose target lies outside
the folder, and returns the resolved path inside it. Errors are :class:`PathError` (a ValueError)
with one line naming the field and what was expected.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_\-]{0,63}$")


class PathError(ValueError):
    def __init__(self, field: str, message: str):
        self.field_path = field
        self.detail = message
        super().__init__(f"{field}: {message}")


def confined(folder: str | os.PathLike, name: str, suffix: str = "", field: str = "name") -> Path:
    """``folder/<name><suffix>``, refused unless it is a plain name whose real path stays in ``folder``."""
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        shown = repr(name)[:60]
        raise PathError(field, f"expected a name of letters, digits, '-' or '_' (max 64, no folders), got {shown}")
    root = Path(folder).resolve()
    candidate = Path(folder) / f"{name}{suffix}"
    real = candidate.resolve()  # follows symlinks (also a dangling one's target)
    if real.parent != root:
        raise PathError(field, f"expected a file inside {root.name}/; {name}{suffix} points outside it")
    return real
