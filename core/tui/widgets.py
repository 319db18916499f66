"""Small widgets shared by the console's screens."""

from __future__ import annotations

from textual.screen import Screen
from textual.widgets import Footer


class KeysFooter(Footer):
    """Textual's footer, recomposed only when the keys it shows change.

    Textual's ``Footer`` rebuilds all its key widgets whenever a screen's bindings are refreshed
    (a dialog opening or closing, a focus change), which costs tens of milliseconds of the event
    loop per key press; the keys themselves rarely change.
    """

    _shown_keys: tuple[tuple[str, str, bool], ...] | None = None

    def bindings_changed(self, screen: Screen) -> None:
        keys = tuple((b.key, b.description, enabled) for _, b, enabled, _ in screen.active_bindings.values() if b.show)
        if keys == self._shown_keys:
            return
        super().bindings_changed(screen)
        if screen.app.app_focus and self.is_attached and screen is self.screen:  # Footer recomposes
            self._shown_keys = keys
