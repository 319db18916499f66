"""Algorithm plugin: marker detection on an image stream (frames stored in a session)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from mirrorlab.core import Algorithm, Parameter, ParameterSet, Port, RunContext

from .errors import InvalidImage
from .stream import detect_stream


class DetectMarkers(Algorithm):
    """Marker centres in every frame: (frames, K_max, 2) px, NaN-padded, plus per-frame counts."""

    name = "detect_markers"
    version = "0.1.0"
    description = "marker centres per frame: sub-pixel centroid (default) or the thesis's hill climbing"
    parameters = ParameterSet(
        Parameter("method", str, "subpixel", choices=("subpixel", "thesis"),
                  help="subpixel: weighted centroid of components; thesis: weighted-filter hill climbing"),
        Parameter("auto_threshold", bool, True, help="Otsu's threshold per frame (else use --threshold)"),
        Parameter("threshold", float, 127.0, bounds=(0.0, None), help="grey level; brighter pixels are markers"),
        Parameter("polarity", str, "bright", choices=("bright", "dark"), help="bright or dark markers"),
        Parameter("min_area", float, 3.0, bounds=(0.0, None), help="smallest marker area, px² (subpixel)"),
        Parameter("max_area", float, 0.0, bounds=(0.0, None), help="largest marker area, px² (0: no limit)"),
        Parameter("max_eccentricity", float, 1.0, bounds=(0.0, 1.0), help="reject more elongated blobs"),
        Parameter("reject_border", bool, True, help="drop blobs touching the image border (subpixel)"),
        Parameter("ellipse", bool, False, help="centre of a fitted ellipse instead of the centroid (subpixel)"),
    )
    inputs = (Port("frames", "(F, H, W) grey or 0/255 binary frames", "grey level"),)
    outputs = (Port("xy", "(F, K_max, 2) centres, x right, y down, pixel centres at integers; NaN-padded", "px"),
               Port("counts", "(F,) markers found per frame"),
               Port("area", "(F, K_max) pixels above threshold, NaN-padded", "px²"),
               Port("eccentricity", "(F, K_max) second-moment eccentricity, NaN-padded"),
               Port("contrast", "(F, K_max) peak minus local background, NaN-padded", "grey level"))
    frame_inputs = ("frames",)  # each frame is detected on its own (Otsu's threshold too)
    roles = ("marker_detector",)  # the console's camera view draws what it finds

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        frames = np.asarray(inputs["frames"])
        if frames.ndim == 2:
            frames = frames[None]
        if frames.ndim not in (3, 4) or frames.shape[0] == 0:
            raise InvalidImage(f"frames must be a (F, H, W) stack of images, got shape {frames.shape}; "
                               "give the frames dataset of an image stream")
        options = dict(method=params["method"], threshold=None if params["auto_threshold"] else params["threshold"],
                       polarity=params["polarity"], min_area=params["min_area"],
                       max_area=params["max_area"] or None, max_eccentricity=params["max_eccentricity"],
                       reject_border=params["reject_border"], ellipse=params["ellipse"])
        out = detect_stream(frames, progress=lambda done, total: context.progress(done, total, "detecting"), **options)
        return {"xy": out.xy, "counts": out.counts, "area": out.area, "eccentricity": out.eccentricity,
                "contrast": out.contrast}


ALGORITHMS = [DetectMarkers]
