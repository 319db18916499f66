"""Recipe steps of the photogrammetry plugin: ``calibrate`` (run a calibration algorithm, optionally on
chessboard image files, and store the camera under ``/calibration/<camera>``) and ``reconstruct``
(run a reconstruction with the camera arrays taken from such a group).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from mirrorlab.core import ALGORITHM_TABLES, Algorithm, Parameter, ParameterSet, PluginError, Problem, Step, algorithm_tables

from .calibration_io import calibration_inputs, chessboard_inputs, parse_pattern, require_new_camera, store_calibration
from .errors import InvalidArgument, PhotogrammetryError

if TYPE_CHECKING:
    from mirrorlab.core import Registry, Session


def _lookup(registry: Registry, name: str, key: str, file: str | None) -> tuple[type[Algorithm] | None, list[Problem]]:
    try:
        return registry.algorithm(name), []
    except PluginError as exc:
        return None, [Problem(key, str(exc), file)]


class Calibrate(Step):
    """``action = "calibrate"``: calibrate a camera and store it under ``/calibration/<camera>``.

    Either ``inputs`` (dataset paths of the session) for ``calibrate_plane`` / ``calibrate_pinhole``,
    or ``images`` (folder or glob of chessboard photos) with ``pattern`` and ``square`` for
    ``calibrate_pinhole``. ``parameters`` go to the algorithm.
    """

    name = "calibrate"
    version = "1.0.0"
    description = "calibrate a camera (plane map or pinhole) and store it under /calibration/<camera>"
    tables = ALGORITHM_TABLES
    parameters = ParameterSet(
        Parameter("camera", str, help="camera name: the result goes to /calibration/<camera>"),
        Parameter("algorithm", str, "calibrate_plane", choices=("calibrate_plane", "calibrate_pinhole"),
                  help="calibration algorithm"),
        Parameter("images", str, "", path=True, help="folder or glob of chessboard photos (calibrate_pinhole)"),
        Parameter("pattern", str, "", help="chessboard inner corners COLSxROWS, e.g. 10x7"),
        Parameter("square", float, 0.0, unit="mm", bounds=(0.0, None),
                  help="chessboard square side (required with images: it sets the scale)"),
        Parameter("detector", str, "classic", choices=("classic", "sb"), help="corner detector"),
    )

    @classmethod
    def validate(cls, table: Mapping[str, Any], where: str, file: str | None,
                 registry: Registry, instruments: Mapping[str, Any]) -> tuple[dict[str, Any], list[Problem]]:
        values, problems = cls.scalars(table, where, file)
        if problems:
            return values, problems
        algorithm, problems = _lookup(registry, values["algorithm"], f"{where}.algorithm", file)
        if algorithm is None:
            return values, problems
        provided: set[str] = set()
        if values["images"]:
            if values["algorithm"] != "calibrate_pinhole":
                problems.append(Problem(f"{where}.images", "images need algorithm = \"calibrate_pinhole\"", file))
            try:
                parse_pattern(values["pattern"])
            except InvalidArgument as exc:
                problems.append(Problem(f"{where}.pattern", str(exc), file))
            if values["square"] <= 0:
                problems.append(Problem(f"{where}.square", "required with images: the chessboard square side in "
                                                           "mm, e.g. square = 25", file))
            provided = {"object_points", "image_points", "image_size"}
        inputs, typed, more = algorithm_tables(algorithm, table, where, file, provided)
        values.update(inputs=inputs, parameters=typed)
        return values, problems + more

    @classmethod
    def session_problems(cls, session: Session, values: Mapping[str, Any], where: str) -> list[Problem]:
        if not session.exists(f"calibration/{values['camera']}"):
            return []
        return [Problem(f"{where}.camera", f"/calibration/{values['camera']} already exists in {session.path.name}; "
                                           "calibration groups are never overwritten")]

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        require_new_camera(session, values["camera"])
        inputs: dict[str, Any] = dict(values["inputs"])
        extra: dict[str, Any] = {}
        attrs: dict[str, Any] = {}
        if values["images"]:
            session.events.progress(self.name, 0, None, "detecting chessboard corners")
            detected, found = chessboard_inputs(values["images"], values["pattern"], values["square"],
                                                values["detector"])
            inputs.update(detected)
            extra = {"image_points": detected["image_points"], "object_points": detected["object_points"]}
            attrs = {"images": str(values["images"]), "pattern": values["pattern"], "square_mm": values["square"],
                     **found}
        ref = session.run(values["algorithm"], inputs, values["parameters"])
        store_calibration(session, values["camera"], ref, extra, attrs)


class Reconstruct(Step):
    """``action = "reconstruct"``: a reconstruction algorithm with the camera of ``/calibration/<camera>``."""

    name = "reconstruct"
    version = "1.0.0"
    description = "reconstruct 3-D markers (parallel, central or mirror) from 2-D marker data of the session"
    tables = ALGORITHM_TABLES
    parameters = ParameterSet(
        Parameter("method", str, "mirror", choices=("parallel", "central", "mirror"), help="reconstruction method"),
        Parameter("calibration", str, "", help="calibration group giving the camera, e.g. /calibration/cam"),
    )

    @classmethod
    def validate(cls, table: Mapping[str, Any], where: str, file: str | None,
                 registry: Registry, instruments: Mapping[str, Any]) -> tuple[dict[str, Any], list[Problem]]:
        values, problems = cls.scalars(table, where, file)
        if problems:
            return values, problems
        algorithm, problems = _lookup(registry, f"reconstruct_{values['method']}", f"{where}.method", file)
        if algorithm is None:
            return values, problems
        if values["calibration"] and not values["calibration"].startswith("/"):
            problems.append(Problem(f"{where}.calibration", "must be a group path such as '/calibration/cam'", file))
        inputs, typed, more = algorithm_tables(algorithm, table, where, file, set())
        values.update(inputs=inputs, parameters=typed)
        return values, problems + more

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        name = f"reconstruct_{values['method']}"
        inputs = dict(values["inputs"])
        if values["calibration"]:
            cls = session.registry.algorithm(name)
            inputs = {**calibration_inputs(session, values["calibration"], cls), **inputs}
        ref = session.run(name, inputs, values["parameters"])
        if ref.status != "ok":
            raise PhotogrammetryError(f"{ref.path} failed: {ref.error}")


STEPS = [Calibrate, Reconstruct]
