"""Built-in algorithm plugins: pure functions wrapped as algorithms, recipe steps, CLI commands and
console screens.

Each sub-package has one shape: modules of pure functions (the mathematics), the adapters
``algorithms.py`` / ``steps.py`` / ``cli.py`` (and ``screen.py`` for a console screen), and a
``plugin.py`` that only registers them through the hooks. Each ``plugin.py`` is an entry point of
the group ``mirrorlab`` of the ``mirrorlab`` distribution (``pyproject.toml``), discovered like any
third-party plugin, so one that fails to import is reported as broken without taking the others
down.

This package itself imports nothing: ``mirrorlab --help`` reads the help of the sub-packages' CLI
commands from :class:`CommandHelp` (through the entry-point group ``mirrorlab.commands``) without
importing any of them.
"""

from __future__ import annotations


class CommandHelp:
    """The one-line help of each built-in plugin's CLI command, as ``mirrorlab --help`` lists it.

    ``pyproject.toml`` points the entry-point group ``mirrorlab.commands`` here
    (``calibrate = "mirrorlab.plugins:CommandHelp.calibrate"``) and declares which plugin adds each
    command (``"command.calibrate"`` in ``mirrorlab.provides``); the plugin's
    ``mirrorlab_add_cli_commands`` builds the parser with the same help.
    """

    calibrate = "calibrate a camera from chessboard photos or from calibration points (CSV)"
    reconstruct = "3-D markers from 2-D marker data: --method parallel|central|mirror"
    kinematics = "marker import/export, derivatives, joint angles, rigid bodies"
    retarget = "chain shape approximation (retargeting) of recorded motion"
    mechanisms = "linkage reconstruction, swept areas, optimal wall"
