"""The demo pipeline glue (issue [demo] item 6): what ties the image chain together.

* :mod:`.grid`: match detected calibration-grid blobs to the grid's points (lattice growth by
  homography, the grid corner fixes the numbering);
* :mod:`.views`: the camera's projection matrix, the image outline of a mirror, and the
  detections inside it (candidate mirror images);
* :mod:`.epipole`: the mirror epipole estimated from unpaired real/mirror detections;
* :mod:`.tracks`: direct/mirror roles from the pairs, and the pairs carried along the tracks of
  the direct images → (F, T, 2) real + virtual;
* :mod:`.report`: errors against the session's ``/truth`` and the figures (``report`` step).

The maths are pure functions; :mod:`.algorithms` and :mod:`.steps` wrap them as algorithms and
the ``report`` step; :mod:`.plugin` registers those.
"""

from .epipole import EpipoleEstimate, estimate_epipole
from .errors import EpipoleError, GridMatchError, PipelineError, SurveyError, ViewSplitError
from .grid import GridMatch, match_grid
from .tracks import assign_views, mirror_tracks
from .views import camera_projection, mirror_outline, split_views

__all__ = ["EpipoleError", "EpipoleEstimate", "GridMatch", "GridMatchError", "PipelineError", "SurveyError",
           "ViewSplitError", "assign_views", "camera_projection", "estimate_epipole", "match_grid",
           "mirror_outline", "mirror_tracks", "split_views"]
