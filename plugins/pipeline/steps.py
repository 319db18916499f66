"""The ``report`` recipe step: the session's measurements against its ``/truth``, printed, stored and plotted."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from mirrorlab.core import Parameter, ParameterSet, Step, figures_folder

if TYPE_CHECKING:
    from mirrorlab.core import Session


class Report(Step):
    """``action = "report"``: measured vs ``/truth`` summary, printed and stored; PNG figures."""

    name = "report"
    version = "1.0.0"
    description = "compare the reconstruction and kinematics with /truth; print the summary; save figures"
    parameters = ParameterSet(
        Parameter("instrument", str, help="label of the recorded RSSR camera (its /truth/<label>)"),
        Parameter("figures", str, "", output="folder",
                  help="folder for the PNG figures (default: <session>-figures next to the file)"),
    )

    instrument_keys = ("instrument",)

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        from .report import build_report, format_report, write_figures

        session.events.progress(self.name, 0, 2, "comparing with truth")
        report = build_report(session, values["instrument"])
        folder = figures_folder(session, values["figures"])
        session.events.progress(self.name, 1, 2, "figures")
        report.figures = write_figures(report, folder)
        report.store(session)
        session.events.progress(self.name, 2, 2, "done")
        print(format_report(report), flush=True)


STEPS = [Report]
