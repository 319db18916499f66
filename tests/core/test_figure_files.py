"""One figure-saving helper and one default figures folder (``mirrorlab.core.figures``), used by every module
that writes PNG files: plugins and instruments save at their resolution into folders they create, and recipe
steps put their figures in ``<session stem>-figures`` beside the session unless told otherwise."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from mirrorlab.core import Session, figures_folder, get_registry, save_figure
from mirrorlab.instruments.virtual_lab.figures import Panel, Trace, plot_traces
from mirrorlab.plugins.kinematics import figures as kin
from mirrorlab.plugins.mechanisms import figures as mech
from mirrorlab.plugins.photogrammetry import figures as pg
from mirrorlab.plugins.pipeline.report import write_figures
from mirrorlab.plugins.retarget.figures import plot_chains

from tests.test_figures import demo_report

t = np.linspace(0.0, 2.0, 30)
X = np.zeros((3, 2, 3))
X[:, 1, 0] = 1.0
XYZ = np.stack([t, t, t], axis=1)[:, None, :]

#: name -> (write a PNG at the given path and return its path or paths, its size in inches, dots per inch):
#: each module's resolution as it was before the modules shared the helper.
WRITERS: dict[str, tuple[Callable[[Path], Path | list[str]], tuple[float, float], float]] = {
    "virtual lab traces": (lambda p: plot_traces(p, [Panel("a", "time (s)", "angle (deg)", [Trace(t, t, "t")])]),
                           (8, 3.8), 100),
    "kinematics derivatives": (lambda p: kin.plot_derivatives(p, t, ["A"], XYZ, XYZ, XYZ), (9, 9), 100),
    "mechanisms swept": (lambda p: mech.plot_swept(p, np.c_[t, 0 * t], np.c_[0 * t, t]), (6.5, 5.5), 100),
    "photogrammetry sweep": (lambda p: pg.plot_mirror_angle_sweep([0.5, 0.7, 0.9], [2.0, 1.0, 2.0], p), (5, 4), 110),
    "retarget chains": (lambda p: plot_chains(p, X, X, [0, 1, 2], [0.0, 0.0, 0.0]), (11, 4.8), 100),
    "demo report trajectories": (lambda p: Path(write_figures(demo_report(), p.parent)[0]), (8, 8), 110),
}


def _png_size(path: Path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n", path
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


@pytest.mark.parametrize("name", WRITERS)
def test_every_writer_saves_a_png_at_its_resolution_into_a_new_folder(name: str, tmp_path: Path) -> None:
    write, inches, dpi = WRITERS[name]
    out = write(tmp_path / "new" / "deeper" / "f.png")
    assert out.parent == tmp_path / "new" / "deeper" and out.is_file()
    assert _png_size(out) == (round(inches[0] * dpi), round(inches[1] * dpi))


def test_save_figure_sets_the_pixels_from_the_size_and_dpi(tmp_path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(3, 2))
    fig.add_subplot().plot([0, 1], [0, 1])
    assert _png_size(save_figure(fig, tmp_path / "a" / "f.png", dpi=110)) == (330, 220)
    assert _png_size(save_figure(fig, tmp_path / "g.png")) == (300, 200)


def test_the_default_folder_is_beside_the_session(tmp_path: Path) -> None:
    with Session.create(tmp_path / "trial.h5") as s:
        assert figures_folder(s, "") == tmp_path / "trial-figures"
        assert figures_folder(s, str(tmp_path / "mine")) == tmp_path / "mine"


@pytest.mark.parametrize("step", ["report", "four_bar_report", "wall_report", "turntable_report", "ultrasonic_report",
                                  "active_mirror_report"])
def test_report_steps_say_where_their_figures_go_by_default(step: str) -> None:
    help_text = get_registry().step(step).parameters["figures"].help
    assert "<session>-figures" in help_text, help_text


def test_the_helpers_do_not_import_matplotlib_until_a_figure_is_saved() -> None:
    code = ("import sys, mirrorlab.core.figures as f; from mirrorlab.core import figures_folder; "
            "print(any(m.split('.')[0] == 'matplotlib' for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out
