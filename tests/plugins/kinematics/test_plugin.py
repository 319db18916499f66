"""The `derivatives` algorithm plugin through a session and through the CLI."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mirrorlab.core import Session

from tests.support import run_cli


def test_derivatives_plugin_in_a_session(tmp_path: Path) -> None:
    t = np.linspace(0.0, 2.0, 201)
    x = np.column_stack([np.sin(2 * np.pi * t), 3.0 * t ** 2])  # mm
    path = tmp_path / "k.h5"
    with Session.create(path) as s:
        s.write_group("truth/signal", {"time": t, "values": x})
        ref = s.run("derivatives", {"time": "/truth/signal/time", "values": "/truth/signal/values"},
                    {"method": "smoothing_spline"})
    assert ref.status == "ok", ref.error
    mid = slice(20, -20)
    with Session.open(path) as s:
        out = s.result(ref).outputs
    # method: GCV on noise-free data stops near lambda = 0 (scipy's bounded search), a small bias on
    # the quadratic; 20 samples from the ends the natural end error has decayed by 0.27^20
    np.testing.assert_allclose(out["velocity"][mid, 1], 6.0 * t[mid], atol=1e-3)

    # the second derivative of that spline: 5 % of the peak (the GCV spline's curvature bias and the
    # h² = 1e-4 s² interpolation term, |f⁗| h² / 12 = 0.1 % here), not a rounding-level claim
    np.testing.assert_allclose(out["acceleration"][mid, 0], -(2 * np.pi) ** 2 * np.sin(2 * np.pi * t[mid]),

                               atol=0.05 * (2 * np.pi) ** 2)

    cli = run_cli("analyze", "derivatives", str(path), "--input", "time=/truth/signal/time",
                  "--input", "values=/truth/signal/values", "--method", "butterworth", "--cutoff", "10 Hz")
    assert cli.returncode == 0, cli.stderr
    assert "/results/derivatives/run-0002: ok" in cli.stdout
