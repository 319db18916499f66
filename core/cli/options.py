"""CLI options generated from typed parameters (the same declarations recipes and TUI forms use)."""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..params import Parameter, ParameterSet


def plain(text: str) -> str:
    """Help text without reStructuredText markup: ``literal``, `name` and :role:`name` become plain.

    >>> plain("see ``--pattern`` and :func:`calibrate`, `frame_rate`")
    'see --pattern and calibrate, frame_rate'
    """
    return re.sub(r"(?::[\w:]+:)?`{1,2}([^`]*)`{1,2}", r"\1", text)


def _show(value: Any) -> str:
    return '""' if value == "" else str(value)


def parameter_facts(d: dict[str, Any]) -> list[str]:
    """Bounds, choices and default of a described parameter (:meth:`Parameter.describe`), for help texts.

    >>> parameter_facts({"bounds": [0.0, None], "choices": None, "required": False, "default": 1.0})
    ['≥ 0.0', 'default 1.0']
    >>> parameter_facts({"bounds": [0, 6], "choices": None, "required": True, "default": None})
    ['0..6', 'required']
    >>> parameter_facts({"bounds": None, "choices": ["", "rssr"], "required": False, "default": ""})
    ['one of "", rssr', 'default ""']
    """
    facts = []
    if d["bounds"]:
        lo, hi = d["bounds"]
        facts.append(f"{lo}..{hi}" if lo is not None and hi is not None else f"≥ {lo}" if lo is not None else f"≤ {hi}")
    if d["choices"]:
        facts.append("one of " + ", ".join(map(_show, d["choices"])))
    facts.append("required" if d["required"] else f"default {_show(d['default'])}")
    return facts


def add_parameter_options(parser: argparse.ArgumentParser, params: ParameterSet, prefix: str = "") -> None:
    """Add ``--<name>`` for each parameter; values stay strings and are validated by the set.

    Booleans take ``--name``/``--no-name``. Numbers accept units (``--exposure "5 ms"``).
    """
    group = parser.add_argument_group(f"{prefix or 'parameters'}")
    for p in params:
        flag = "--" + p.name.replace("_", "-")
        unit = f" [{p.unit}]" if p.unit else ""
        text = f"{plain(p.help)}{unit} ({'; '.join(parameter_facts(p.describe()))})"
        dest = f"param__{p.name}"
        if p.type is bool:
            group.add_argument(flag, dest=dest, action=argparse.BooleanOptionalAction, default=None, help=text)
        else:
            group.add_argument(flag, dest=dest, default=None, metavar=p.type_name.upper(), help=text)


def parameter_type(parameter: Parameter) -> Callable[[str], Any]:
    """argparse ``type`` for a hand-written option: the text checked as ``parameter``.

    Units are converted as in recipes (a ``mm`` parameter takes ``25``, ``"25 mm"``, ``"2.5 cm"``);
    a bad value is a usage error naming the option.

    >>> parameter_type(Parameter("square", float, unit="mm"))("2.5 cm")
    25.0
    """
    def parse(text: str) -> Any:
        value, reason = parameter.check(text)
        if reason:
            raise argparse.ArgumentTypeError(reason)
        return value

    return parse


def existing_path(text: str) -> Path:
    """argparse ``type`` for an input file or folder: a missing one is a usage error (exit 2)."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"no such file or folder {text!r}; check the path")
    return path


def collected(args: argparse.Namespace) -> dict[str, Any]:
    """The parameter values given on the command line (unset ones are left to defaults)."""
    return {k[len("param__"):]: v for k, v in vars(args).items() if k.startswith("param__") and v is not None}
