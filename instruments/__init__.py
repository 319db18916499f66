"""Built-in instrument plugins; each sub-package is one instrument with its simulator."""

from __future__ import annotations

from mirrorlab.core.hookspecs import hookimpl


@hookimpl
def mirrorlab_register_instruments() -> list[type]:
    from .film_scanner import FilmScanner

    return [FilmScanner]
