"""Fuzzing recipes: random TOML text, random bytes, random types for every known key, random ``--set``.

Whatever the input, :func:`~mirrorlab.core.recipes.load_recipe` either returns a recipe or raises a
:class:`~mirrorlab.core.errors.ValidationError` whose every problem names the file, a key (or the
whole file) and the reason; ``mirrorlab run --check`` turns that into exit 2 and one line per
problem, never a traceback.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mirrorlab.core.errors import ValidationError
from mirrorlab.core.recipes import load_recipe
from mirrorlab.core.registry import get_registry

from tests.support import REPO

#: A valid recipe touching every kind of key: session, an instrument with settings and simulator
#: options, and the acquire, wait and run steps (a run with inputs and parameters).
BASE: dict[str, Any] = {
    "session": {"description": "fuzz", "operator": "ana"},
    "instruments": {"cam": {"plugin": "film_scanner", "simulate": True, "port": "", "timeout": 2.0,
                            "settings": {"source": "fscan", "lines": 64, "threshold": 128, "clock_hz": "73 kHz"},
                            "simulator": {"clock": "FAST", "seed": 1}}},
    "steps": [{"action": "acquire", "seconds": 1.0, "instruments": "cam"},
              {"action": "wait", "seconds": 0.5},
              {"action": "run", "algorithm": "filter",
               "inputs": {"time": "/instruments/cam/frame_index/time", "values": "/instruments/cam/frame_index/data"},
               "parameters": {"method": "butterworth", "cutoff": "5 Hz"}}],
}

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

text = st.text(st.characters(exclude_categories=("Cs",)), max_size=20)  # TOML strings are Unicode scalars
scalars = st.one_of(st.booleans(), st.integers(-2**63, 2**63 - 1), st.floats(allow_nan=True, allow_infinity=True),
                    text, st.datetimes(), st.dates(), st.times())
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(text, inner, max_size=4)), max_leaves=8)


def toml_string(s: str) -> str:
    """A TOML basic string: quote and backslash escaped, control characters as \\uXXXX."""
    return '"' + "".join("\\" + c if c in '"\\' else f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F else c
                         for c in s) + '"'


def toml_value(v: Any) -> str:
    """``v`` as a TOML value (inline tables and arrays; tomllib reads back exactly these)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return toml_string(v)
    if isinstance(v, list):
        return "[" + ", ".join(map(toml_value, v)) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{toml_string(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    return v.isoformat()  # datetime, date, time


def toml_document(doc: dict[str, Any]) -> str:
    return "".join(f"{toml_string(k)} = {toml_value(v)}\n" for k, v in doc.items())


def key_paths(node: Any, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    """Every key path of a document (tables and array items), the document itself excluded."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        yield prefix + (k,)
        yield from key_paths(v, prefix + (k,))


PATHS = sorted(key_paths(BASE), key=str)


def replaced(doc: Any, path: tuple[Any, ...], value: Any) -> Any:
    copy = json.loads(json.dumps(doc))
    node = copy
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return copy


@pytest.fixture(scope="module")
def registry() -> Any:
    return get_registry()


@pytest.fixture(scope="module")
def folder() -> Iterator[Path]:
    with tempfile.TemporaryDirectory() as d:
        yield Path(d)


def check(path: Path, overrides: tuple[str, ...] = (), registry: Any = None) -> list[str]:
    """Load ``path``; on a ValidationError check that every problem is well formed; return the lines."""
    try:
        load_recipe(path, overrides, registry=registry)
    except ValidationError as exc:
        assert exc.problems
        lines = [str(p) for p in exc.problems]
        for problem, line in zip(exc.problems, lines):
            assert problem.reason.strip(), line
            if not problem.key.startswith("--set"):  # an option's problem names the option instead
                assert problem.file == str(path) and line.startswith(f"{path}: "), line
        return lines
    return []


def test_the_base_recipe_is_valid(folder: Path, registry: Any) -> None:
    path = folder / "base.toml"
    path.write_text(toml_document(BASE))
    assert check(path, registry=registry) == []


@FUZZ
@given(data=st.data())
def test_random_type_for_every_known_key(data: st.DataObject, folder: Path, registry: Any) -> None:
    key = data.draw(st.sampled_from(PATHS))
    value = data.draw(values)
    path = folder / "typed.toml"
    path.write_text(toml_document(replaced(BASE, key, value)))
    lines = check(path, registry=registry)
    dotted = ".".join(map(str, key))
    for line in lines:  # the mutated key (or its table, or a key inside it) is the one blamed
        where = line[len(f"{path}: "):].split(": ")[0]
        assert dotted.startswith(where) or where.startswith(dotted) or where.startswith("steps"), (dotted, lines)


@FUZZ
@given(doc=st.dictionaries(st.one_of(st.sampled_from(["session", "instruments", "steps"]), text), values, max_size=4))
def test_random_toml_documents(doc: dict[str, Any], folder: Path, registry: Any) -> None:
    path = folder / "random.toml"
    path.write_text(toml_document(doc))
    assert check(path, registry=registry)  # no steps at least: never a valid recipe


@FUZZ
@given(body=st.text(max_size=300))
def test_random_text(body: str, folder: Path, registry: Any) -> None:
    path = folder / "text.toml"
    path.write_bytes(body.encode("utf-8", "surrogatepass"))
    check(path, registry=registry)


@FUZZ
@given(body=st.binary(max_size=300))
def test_random_bytes(body: bytes, folder: Path, registry: Any) -> None:
    path = folder / "bytes.toml"
    path.write_bytes(body)
    check(path, registry=registry)


@FUZZ
@given(overrides=st.lists(st.one_of(
    st.builds(lambda k, v: f"{'.'.join(map(str, k))}={v}", st.sampled_from(PATHS), st.one_of(text, values.map(toml_value))),
    text), max_size=3))
def test_random_overrides(overrides: list[str], folder: Path, registry: Any) -> None:
    path = folder / "set.toml"
    path.write_text(toml_document(BASE))
    check(path, tuple(overrides), registry)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(body=st.one_of(st.binary(min_size=1, max_size=200), st.text(min_size=1, max_size=200).map(str.encode)))
def test_run_check_answers_exit_2_with_one_line_per_problem(body: bytes, folder: Path) -> None:
    path = folder / "cli.toml"
    path.write_bytes(body)
    proc = subprocess.run([sys.executable, "-m", "mirrorlab.core.cli", "run", str(path), "--check"],
                          capture_output=True, text=True, cwd=REPO, timeout=120)
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    lines = proc.stderr.splitlines()
    assert lines and all(line.startswith(f"mirrorlab: error: {path}: ") for line in lines), proc.stderr
