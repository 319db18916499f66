"""CLI options generated from typed parameters (the same declarations recipes and TUI forms use)."""

from __future__ import annotations

import argparse
from typing import Any

from ..params import ParameterSet


def add_parameter_options(parser: argparse.ArgumentParser, params: ParameterSet, prefix: str = "") -> None:
    """Add ``--<name>`` for each parameter; values stay strings and are validated by the set.

    Booleans take ``--name``/``--no-name``. Numbers accept units (``--exposure "5 ms"``).
    """
    group = parser.add_argument_group(f"{prefix or 'parameters'}")
    for p in params:
        flag = "--" + p.name.replace("_", "-")
        unit = f" [{p.unit}]" if p.unit else ""
        extra = []
        if p.choices:
            extra.append("one of " + ", ".join(map(str, p.choices)))
        if p.bounds:
            extra.append(f"range {p.bounds[0]}..{p.bounds[1]}")
        default = "required" if p.required else f"default {p.default}"
        text = f"{p.help}{unit} ({'; '.join(extra + [default])})"
        dest = f"param__{p.name}"
        if p.type is bool:
            group.add_argument(flag, dest=dest, action=argparse.BooleanOptionalAction, default=None, help=text)
        else:
            group.add_argument(flag, dest=dest, default=None, metavar=p.type_name.upper(), help=text)


def collected(args: argparse.Namespace) -> dict[str, Any]:
    """The parameter values given on the command line (unset ones are left to defaults)."""
    return {k[len("param__"):]: v for k, v in vars(args).items() if k.startswith("param__") and v is not None}
