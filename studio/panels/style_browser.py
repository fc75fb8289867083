"""Style browser: open, save, save as, new (from neutral), recover autosaved edits."""

from __future__ import annotations

from typing import TYPE_CHECKING

import viser

if TYPE_CHECKING:
    from studio.style_session import StyleSession


class StyleBrowser:
    def __init__(self, server: viser.ViserServer, session: "StyleSession", notify):
        self.server = server
        self.session = session
        self.notify = notify  # (level, text) → shown to the user
        names = session.style_names() or ["neutral"]
        current = session.path.stem if session.path else names[0]
        self.title = server.gui.add_markdown("")
        self.dropdown = server.gui.add_dropdown("Style", options=tuple(names), initial_value=current)
        self.open_button = server.gui.add_button("Open", icon=viser.Icon.FOLDER_OPEN)
        self.recover_button = server.gui.add_button("Recover unsaved edits", icon=viser.Icon.LIFEBUOY, color="yellow",
                                                    visible=False)
        self.save_button = server.gui.add_button("Save", icon=viser.Icon.DEVICE_FLOPPY)
        self.name = server.gui.add_text("New name", initial_value="", hint="name for Save as / New from neutral: "
                                                                          "letters, digits, - and _")
        self.save_as_button = server.gui.add_button("Save as", icon=viser.Icon.COPY)
        self.new_button = server.gui.add_button("New from neutral", icon=viser.Icon.FILE_PLUS)
        self.open_button.on_click(self._on_open)
        self.recover_button.on_click(self._on_recover)
        self.save_button.on_click(self._on_save)
        self.save_as_button.on_click(self._on_save_as)
        self.new_button.on_click(self._on_new)
        self.dropdown.on_update(lambda _: self._offer_recovery())
        session.subscribe(lambda style, reason: self.refresh())
        self.refresh()


    # button callbacks (viser wants callbacks returning None; the actions return whether they acted)
    def _on_open(self, _event: object) -> None:
        self.open(self.dropdown.value)

    def _on_recover(self, _event: object) -> None:
        self.recover()

    def _on_save(self, _event: object) -> None:
        self.save()

    def _on_save_as(self, _event: object) -> None:
        self.save_as(self.name.value.strip())

    def _on_new(self, _event: object) -> None:
        self.new(self.name.value.strip())

    def _report(self, result) -> bool:
        self.notify("info" if result.ok else "error", result.message)
        self.refresh()
        return result.ok

    def open(self, name: str) -> bool:
        if self.session.dirty:
            self.notify("warning", f"unsaved edits of {self.session.path.stem if self.session.path else 'the style'} "
                                   "stay in its recovery file")
        return self._report(self.session.open(name))

    def recover(self) -> bool:
        return self._report(self.session.recover(self.dropdown.value))

    def save(self) -> bool:
        return self._report(self.session.save())

    def save_as(self, name: str) -> bool:
        ok = self._report(self.session.save_as(name))
        if ok:
            self._refresh_names(name)
        return ok

    def new(self, name: str) -> bool:
        ok = self._report(self.session.new_from("neutral", name))
        if ok:
            self._refresh_names(name)
        return ok

    def _refresh_names(self, current: str) -> None:
        names = self.session.style_names()
        self.dropdown.options = tuple(names)
        self.dropdown.value = current  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only

    def _offer_recovery(self) -> None:
        self.recover_button.visible = self.session.recovery_available(self.dropdown.value)

    def refresh(self) -> None:
        session = self.session
        name = session.path.stem if session.path else "—"
        marker = " ● unsaved" if session.dirty else ""
        self.title.content = f"**{name}**{marker}"
        self._offer_recovery()
