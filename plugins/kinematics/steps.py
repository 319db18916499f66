"""Recipe step of the kinematics plugin: ``import_markers`` (a C3D / TRC / TSV file into ``/markers``)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mirrorlab.core import Parameter, ParameterSet, Problem, Step, identifier_problem

if TYPE_CHECKING:
    from mirrorlab.core import Registry, Session


class ImportMarkers(Step):
    """Recipe step ``import_markers``: copy a C3D/TRC/TSV file into ``/markers/<name>``.

    .. code-block:: toml

        [[steps]]
        action = "import_markers"
        file = "trial01.c3d"       # relative to the recipe file
        name = "trial01"           # optional; default: the file's stem
        format = "auto"            # auto (from the suffix), c3d, trc, tsv
    """

    name = "import_markers"
    version = "0.1.0"
    description = "import a C3D, TRC or Qualisys TSV marker file into the session as /markers/<name>"
    parameters = ParameterSet(
        Parameter("file", Path, help="marker file (.c3d, .trc, .tsv)"),
        Parameter("name", str, "", help="dataset name under /markers (default: the file's stem)"),
        Parameter("format", str, "auto", choices=("auto", "c3d", "trc", "tsv"), help="file format"),
    )

    @classmethod
    def check(cls, values: Mapping[str, Any], where: str, file: str | None, registry: Registry) -> list[Problem]:
        path = Path(values["file"])
        if values["name"] and (reason := identifier_problem(values["name"])):  # it names /markers/<name>
            return [Problem(f"{where}.name", reason, file)]
        if not path.is_file():
            return [Problem(f"{where}.file", f"no such marker file {str(values['file'])!r}", file)]
        if values["format"] == "auto" and path.suffix.lower() not in (".c3d", ".trc", ".tsv"):
            return [Problem(f"{where}.format", "cannot tell the format from the suffix; set format", file)]
        return []

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        from .store import import_markers

        group, data = import_markers(session, values["file"], values["name"] or None, values["format"])
        session.events.emit("info", "kinematics", "markers_imported",
                            f"{values['file']} -> {group}: {data.points.shape[1]} markers, "
                            f"{data.points.shape[0]} frames at {data.rate:g} Hz")


STEPS = [ImportMarkers]
