"""Recipe steps of the photogrammetry plugin: ``calibrate`` (run a calibration algorithm, optionally on
chessboard image files, and store the camera under ``/calibration/<camera>``) and ``reconstruct``
(run a reconstruction with the camera arrays taken from such a group).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from mirrorlab.core import AlgorithmStep, Parameter, ParameterSet, Problem

from .calibration_io import calibration_inputs, chessboard_inputs, parse_pattern, require_new_camera, store_calibration
from .errors import InvalidArgument, PhotogrammetryError

if TYPE_CHECKING:
    from mirrorlab.core import Registry, Session


class Calibrate(AlgorithmStep):
    """``action = "calibrate"``: calibrate a camera and store it under ``/calibration/<camera>``.

    Either ``inputs`` (dataset paths of the session) for ``calibrate_plane`` / ``calibrate_pinhole``,
    or ``images`` (folder or glob of chessboard photos) with ``pattern`` and ``square`` for
    ``calibrate_pinhole``. ``parameters`` go to the algorithm.
    """

    name = "calibrate"
    version = "1.0.0"
    description = "calibrate a camera (plane map or pinhole) and store it under /calibration/<camera>"
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
    def provided(cls, values: Mapping[str, Any]) -> set[str]:
        return {"object_points", "image_points", "image_size"} if values["images"] else set()

    @classmethod
    def check(cls, values: Mapping[str, Any], where: str, file: str | None, registry: Registry) -> list[Problem]:
        if not values["images"]:
            return []
        problems = []
        if values["algorithm"] != "calibrate_pinhole":
            problems.append(Problem(f"{where}.images", "images need algorithm = \"calibrate_pinhole\"", file))
        try:
            parse_pattern(values["pattern"])
        except InvalidArgument as exc:
            problems.append(Problem(f"{where}.pattern", str(exc), file))
        if values["square"] <= 0:
            problems.append(Problem(f"{where}.square", "required with images: the chessboard square side in "
                                                       "mm, e.g. square = 25", file))
        return problems

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


class Reconstruct(AlgorithmStep):
    """``action = "reconstruct"``: a reconstruction algorithm with the camera of ``/calibration/<camera>``."""

    name = "reconstruct"
    version = "1.0.0"
    description = "reconstruct 3-D markers (parallel, central or mirror) from 2-D marker data of the session"
    algorithm_key = "method"
    failure = PhotogrammetryError
    parameters = ParameterSet(
        Parameter("method", str, "mirror", choices=("parallel", "central", "mirror"), help="reconstruction method"),
        Parameter("calibration", str, "", help="calibration group giving the camera, e.g. /calibration/cam"),
    )

    @classmethod
    def algorithm_name(cls, values: Mapping[str, Any]) -> str:
        return f"reconstruct_{values['method']}"

    @classmethod
    def check(cls, values: Mapping[str, Any], where: str, file: str | None, registry: Registry) -> list[Problem]:
        if values["calibration"] and not values["calibration"].startswith("/"):
            return [Problem(f"{where}.calibration", "must be a group path such as '/calibration/cam'", file)]
        return []

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        name = self.algorithm_name(values)
        inputs = dict(values["inputs"])
        if values["calibration"]:
            cls = session.registry.algorithm(name)
            inputs = {**calibration_inputs(session, values["calibration"], cls), **inputs}
        self.run_algorithm(session, name, inputs, values["parameters"])


STEPS = [Calibrate, Reconstruct]
