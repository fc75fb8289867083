"""The style being edited: current document, file, undo/redo, autosave, validation.

Panels never change a style directly: they call :meth:`StyleSession.apply` with a new
(immutable) style built by the engine's editing operations. Every edit is validated with
the robot's rules first — an edit that would break a constraint is refused with the
validator's one-line message and the style stays valid. Accepted edits go on the undo
stack, mark the session dirty, are written to a recovery file (autosave) and are pushed to
listeners (the engine link, the panels).
"""

from __future__ import annotations

import json
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from engine.atomic_io import atomic_write_text
from engine.paths import NAME_PATTERN, PathError, confined
from engine.gait.style import (
    Style,
    StyleContext,
    StyleError,
    dumps_style,
    load_style,
    style_from_dict,
    styles_dir,
    validate_style,
)

UNDO_LIMIT = 200


@dataclass(frozen=True)
class EditResult:
    ok: bool
    message: str = ""


class StyleSession:
    """One robot's style being edited in the studio (thread-safe)."""

    def __init__(self, robot: str, ctx: StyleContext | None = None, folder: Path | None = None):
        self.robot = robot
        self.ctx = ctx or StyleContext.for_robot(robot)
        self.folder = Path(folder) if folder is not None else styles_dir(robot)
        self.style: Style | None = None
        self.path: Path | None = None
        self.dirty = False
        self._undo: list[tuple[Style, str]] = []
        self._redo: list[tuple[Style, str]] = []
        self._merge_key: object | None = None  # edits with the newest entry's key coalesce into it
        self._listeners: list[Callable[[Style, str], None]] = []
        self._urgent_listeners: list[Callable[[Style, str], None]] = []
        self._lock = threading.RLock()
        self.last_error = ""
        self.warn: Callable[[str], None] | None = None  # tells the user (autosave failures)
        self._autosave_failed = False

    # ------------------------------------------------------------------ listeners
    def subscribe(self, callback: Callable[[Style, str], None], *, urgent: bool = False) -> None:
        """``callback(style, reason)`` after every change (edit, undo, open, ...).

        ``urgent`` listeners (the engine link: what the robot walks) hear of an edit first, before
        it is autosaved; the others (panels) after.
        """
        (self._urgent_listeners if urgent else self._listeners).append(callback)

    def unsubscribe(self, callback: Callable[[Style, str], None]) -> None:
        for listeners in (self._urgent_listeners, self._listeners):
            if callback in listeners:
                listeners.remove(callback)

    def _notify(self, reason: str, *, urgent: bool | None = None) -> None:
        """Tell the listeners (``urgent``: True only the urgent ones, False only the others, None all)."""
        style = self.style
        if style is None:
            return
        groups = {True: [self._urgent_listeners], False: [self._listeners], None: [self._urgent_listeners, self._listeners]}
        for listeners in groups[urgent]:
            for callback in list(listeners):
                callback(style, reason)

    def _commit(self, reason: str) -> None:
        """After an edit, undo or redo: the engine hears of it, it is autosaved, then the panels."""
        self._notify(reason, urgent=True)
        with self._lock:
            self._autosave()
        self._notify(reason, urgent=False)

    # ------------------------------------------------------------------ files
    def style_names(self) -> list[str]:
        return sorted(p.stem for p in self.folder.glob("*.json") if NAME_PATTERN.match(p.stem))

    def path_for(self, name: str) -> Path:
        """``styles/<robot>/<name>.json`` — names only, so pickers never leave the folder."""
        try:
            return confined(self.folder, name, ".json")
        except PathError as exc:
            raise StyleError(exc.field_path, exc.detail, "style") from None

    def recovery_path(self, name: str) -> Path:
        try:
            path = confined(self.folder / ".autosave", name, ".json")
        except PathError as exc:
            raise StyleError(exc.field_path, exc.detail, "recovery") from None
        if path.parent.parent != self.folder.resolve():  # .autosave itself must not lead elsewhere
            raise StyleError("name", "expected the .autosave folder inside the styles folder", "recovery")
        return path

    def open(self, name: str) -> EditResult:
        try:
            path = self.path_for(name)
            style = load_style(path, self.ctx, expected_robot=self.robot)
        except StyleError as exc:
            return self._refuse(str(exc))
        with self._lock:
            self.style, self.path, self.dirty = style, path, False
            self._merge_key = None
            self._undo.clear()
            self._redo.clear()
        self._notify("open")
        return EditResult(True, f"opened {name}")

    def recovery_available(self, name: str) -> bool:
        """Unsaved edits of ``name`` wait in its recovery file (a crash, or edits left by opening another
        style) — not the open style's own autosave while its edits are still here, nor a copy of the file."""
        try:
            rec = self.recovery_path(name)
        except StyleError:
            return False
        target = self.folder / f"{name}.json"
        if not rec.is_file():
            return False
        if self.path is not None and self.path.stem == name and self.dirty:
            return False  # the recovery file mirrors the edits this session holds
        try:
            if target.is_file() and rec.stat().st_mtime <= target.stat().st_mtime:
                return False
            return not target.is_file() or json.loads(rec.read_text()) != json.loads(target.read_text())
        except (OSError, ValueError):
            return True

    def recover(self, name: str) -> EditResult:
        """Open the autosaved (unsaved) edits of ``name``; the session is dirty afterwards."""
        try:
            rec = self.recovery_path(name)
            style = load_style(rec, self.ctx, expected_robot=self.robot)
        except StyleError as exc:
            return self._refuse(str(exc))
        with self._lock:
            self.style, self.path, self.dirty = style, self.path_for(name), True
            self._undo.clear()
            self._redo.clear()
        self._notify("recover")
        return EditResult(True, f"recovered unsaved edits of {name}")

    def save(self) -> EditResult:
        with self._lock:
            if self.style is None or self.path is None:
                return self._refuse("nothing to save")
            try:
                atomic_write_text(self.path, dumps_style(self.style))  # the old file stays whole on failure
            except OSError as exc:  # full disk, read-only folder, ...: say so; the edits stay open and dirty
                kept = "" if self._autosave_failed else " and in the recovery file"
                return self._refuse(f"could not save {self.path.name}: {exc.strerror or exc}; your edits stay "
                                    f"open{kept}")
            self.dirty = False
            self.recovery_path(self.path.stem).unlink(missing_ok=True)
        self._notify("save")
        return EditResult(True, f"saved {self.path.name}")

    def save_as(self, name: str) -> EditResult:
        try:
            path = self.path_for(name)
        except StyleError as exc:
            return self._refuse(str(exc))
        with self._lock:
            if self.style is None:
                return self._refuse("nothing to save")
            from dataclasses import replace

            self.style = replace(self.style, name=name)
            self.path = path
        return self.save()

    def new_from(self, template: str, name: str) -> EditResult:
        """A new style file ``name`` starting as a copy of ``template`` (e.g. neutral)."""
        try:
            path = self.path_for(name)
        except StyleError as exc:
            return self._refuse(str(exc))
        if path.exists():
            return self._refuse(f"{path.name} exists already")
        result = self.open(template)
        if not result.ok:
            return result
        return self.save_as(name)

    # ------------------------------------------------------------------ editing
    def apply(self, new_style: Style, label: str, merge_key: object | None = None) -> EditResult:
        """Validate and commit an edit; refused edits leave the style untouched.

        Consecutive edits with the same ``merge_key`` (e.g. the live updates of one mouse drag)
        share one undo entry: undo returns to the style before the first of them.
        """
        try:
            validate_style(new_style, self.ctx)
        except StyleError as exc:
            return self._refuse(str(exc))
        with self._lock:
            if self.style is None:
                return self._refuse("no style open")
            if merge_key is None or merge_key != self._merge_key or not self._undo:
                self._undo.append((self.style, label))
                del self._undo[:-UNDO_LIMIT]
            self._merge_key = merge_key
            self._redo.clear()
            self.style = new_style
            self.dirty = True
        self._commit(f"edit: {label}")
        return EditResult(True, label)

    def undo(self) -> EditResult:
        with self._lock:
            if not self._undo:
                return EditResult(False, "nothing to undo")
            previous, label = self._undo.pop()
            self._merge_key = None
            if self.style is not None:
                self._redo.append((self.style, label))
            self.style = previous
            self.dirty = True
        self._commit(f"undo: {label}")
        return EditResult(True, f"undid {label}")

    def redo(self) -> EditResult:
        with self._lock:
            if not self._redo:
                return EditResult(False, "nothing to redo")
            following, label = self._redo.pop()
            self._merge_key = None
            if self.style is not None:
                self._undo.append((self.style, label))
            self.style = following
            self.dirty = True
        self._commit(f"redo: {label}")
        return EditResult(True, f"redid {label}")

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)

    def undo_labels(self) -> list[str]:
        return [label for _, label in self._undo]

    def _autosave(self) -> None:
        if self.style is None or self.path is None:
            return
        rec = self.recovery_path(self.path.stem)
        try:
            atomic_write_text(rec, dumps_style(self.style))
        except OSError as exc:  # a full disk must not lose the edit in memory
            self.last_error = f"autosave failed: {exc.strerror or exc}; the edits are only in memory, save elsewhere"
            if not self._autosave_failed and self.warn is not None:
                self.warn(self.last_error)  # once per failure streak
            self._autosave_failed = True
        else:
            self._autosave_failed = False

    def _refuse(self, message: str) -> EditResult:
        self.last_error = message
        return EditResult(False, message)

    # ------------------------------------------------------------------ engine
    def as_document(self) -> dict:
        """The style as its JSON document (what travels to the engine)."""
        assert self.style is not None
        return json.loads(dumps_style(self.style))


def style_from_document(doc: dict, ctx: StyleContext) -> Style:
    return style_from_dict(doc, ctx, expected_robot=ctx.robot)
