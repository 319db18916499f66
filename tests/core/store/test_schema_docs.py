"""The README and the documents name the session schema version that the store writes (issue 19)."""

from __future__ import annotations

import re

from mirrorlab.core.store.schema import SCHEMA_VERSION

from tests.support import REPO

CURRENT = re.compile(r"schema \(?v(\d+)\)?")  # "schema v2", "schema (v2)"; "a schema 1 file" names an old one


def test_documents_name_the_schema_version_written() -> None:
    texts = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md")), *sorted((REPO / "core" / "store").glob("*.py"))]
    named = {(path.relative_to(REPO).as_posix(), int(v)) for path in texts for v in CURRENT.findall(path.read_text())}
    assert ("README.md", SCHEMA_VERSION) in named, "the README names the session schema with its version"
    assert {(where, v) for where, v in named if v != SCHEMA_VERSION} == set(), f"schema.SCHEMA_VERSION is {SCHEMA_VERSION}"
