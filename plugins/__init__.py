"""Built-in algorithm plugins: pure functions wrapped as algorithms, recipe steps and CLI commands.

Each sub-package has one shape: modules of pure functions (the mathematics), the adapters
``algorithms.py`` / ``steps.py`` / ``cli.py``, and a ``plugin.py`` that only registers them through
the registration hooks. Each ``plugin.py`` is an entry point of the group ``mirrorlab`` of the
``mirrorlab`` distribution (``pyproject.toml``), discovered like any third-party plugin, so one
that fails to import is reported as broken without taking the others down.

Their CLI commands are declared in :data:`CLI_COMMANDS`, so that the ``mirrorlab`` command lists
them without importing any sub-package.
"""

from __future__ import annotations

#: CLI sub-commands of the sub-packages: name -> (one-line help, ``"module:function"`` adding the parser).
#: ``mirrorlab --help`` lists them from here; the module is imported only when the command runs.
CLI_COMMANDS = {
    "calibrate": ("calibrate a camera from chessboard photos or from calibration points (CSV)",
                  f"{__name__}.photogrammetry.cli:add"),
    "reconstruct": ("3-D markers from 2-D marker data: --method parallel|central|mirror",
                    f"{__name__}.photogrammetry.cli:add"),
    "kinematics": ("marker import/export, derivatives, joint angles, rigid bodies",
                   f"{__name__}.kinematics.cli:add"),
    "retarget": ("chain shape approximation (retargeting) of recorded motion",
                 f"{__name__}.retarget.cli:add"),
    "mechanisms": ("linkage reconstruction, swept areas, optimal wall",
                   f"{__name__}.mechanisms.cli:add"),
}
