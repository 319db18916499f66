"""The session browser: the HDF5 tree of the session file; the highlighted group or dataset's
attributes (provenance pretty-printed) and first values. The file is read in worker threads."""

from __future__ import annotations

from typing import TYPE_CHECKING

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, VerticalScroll
from textual.screen import Screen
from textual.widgets import Header, Static, Tree

from . import browse
from .widgets import KeysFooter

if TYPE_CHECKING:
    from .app import MirrorlabApp


class BrowserScreen(Screen[None]):
    """``b`` on the dashboard: ↑ ↓ move, → / enter open a group, f5 reloads, esc goes back."""

    BINDINGS = [Binding("f5", "reload", "Reload"), Binding("escape", "back", "Back")]
    DEFAULT_CSS = """
    BrowserScreen #tree { width: 34; height: 1fr; }
    BrowserScreen #detail-pane { width: 1fr; height: 1fr; padding: 0 1; }
    BrowserScreen #detail { height: auto; }
    """

    app: MirrorlabApp

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal():
            tree: Tree[browse.Node] = Tree(self.app.model.session.path.name, id="tree")
            tree.show_root = False
            yield tree
            with VerticalScroll(id="detail-pane"):
                yield Static("reading the file…", id="detail", markup=False)
        yield KeysFooter()

    def on_mount(self) -> None:
        self.sub_title = "session file"
        self.query_one("#tree", Tree).focus()
        self.action_reload()

    def action_reload(self) -> None:
        self.app.in_worker("read the session file", lambda: browse.walk(self.app.model.session), self._fill, owner=self)

    def _fill(self, nodes: object) -> None:
        tree = self.query_one("#tree", Tree)
        tree.clear()
        parents = {"": tree.root}
        for node in nodes:  # type: ignore[attr-defined]
            parent = parents[node.path.rsplit("/", 1)[0]]  # "/a" → "" (the root), "/a/b" → "/a"
            if node.is_dataset:
                parent.add_leaf(browse.label(node), data=node)
            else:
                parents[node.path] = parent.add(node.name, data=node)
        self.query_one("#detail", Static).update(f"{len(nodes)} groups and datasets; "  # type: ignore[arg-type]
                                                 "↑ ↓ to move, → or enter to open a group")

    def on_tree_node_highlighted(self, event: Tree.NodeHighlighted[browse.Node]) -> None:
        node = event.node.data
        if node is None:
            return
        path = node.path
        self.app.in_worker(f"read {path}", lambda: browse.describe(self.app.model.session, path),
                           lambda text: self._show(path, str(text)), owner=self)

    def _show(self, path: str, text: str) -> None:
        tree = self.query_one("#tree", Tree)
        current = tree.cursor_node.data if tree.cursor_node is not None else None
        if current is not None and current.path == path:  # the operator may have moved on meanwhile
            self.query_one("#detail", Static).update(text)

    def action_back(self) -> None:
        self.app.pop_screen()
