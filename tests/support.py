"""Helpers shared by the test modules (import as ``from tests.support import ...``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
THIRDPARTY = HERE / "thirdparty"
SHARED_DATA = REPO.parent / "shared" / "data"


def pip_install_target(package: Path, target: Path) -> Path:
    """``pip install --target`` a test plugin (no dependencies: mirrorlab is already installed)."""
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    "--target", str(target), str(package)], check=True)
    return target


def run_cli(*args: str, sites: tuple[Path, ...] = (), cwd: Path | None = None,
            timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """Run the ``mirrorlab`` CLI in a subprocess (with extra site directories on PYTHONPATH)."""
    env = dict(os.environ)
    if sites:
        env["PYTHONPATH"] = os.pathsep.join([*map(str, sites), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return subprocess.run([sys.executable, "-m", "mirrorlab.core.cli", *args], capture_output=True, text=True,
                          env=env, cwd=cwd or REPO, timeout=timeout)
