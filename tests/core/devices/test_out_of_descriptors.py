"""A process out of file descriptors is told so, not sent to check its cables or its disk (issue 20, item 7).

The limit is lowered in a subprocess of its own (``resource.setrlimit``), which then holds every
descriptor left and opens a real pseudo-terminal by path and a real session file."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

from tests.support import make_small_session

SCRIPT = textwrap.dedent("""
    import os, resource, sys
    from mirrorlab.core.devices.transport import open_port
    from mirrorlab.core.errors import MirrorlabError
    from mirrorlab.core import Session
    master, slave = os.openpty()
    port = os.ttyname(slave)
    resource.setrlimit(resource.RLIMIT_NOFILE, (64, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
    held = []
    try:
        while True:
            held.append(os.open(os.devnull, os.O_RDONLY))
    except OSError:
        pass
    for what, attempt in (("port", lambda: open_port(port)), ("file", lambda: Session.open(sys.argv[1]))):
        try:
            attempt()
        except MirrorlabError as exc:
            print(what, exc)
""")


def test_too_many_open_files_says_so(tmp_path: Path, acme_site: Path) -> None:
    session = make_small_session(tmp_path / "small.h5", acme_site)
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(session)], capture_output=True, text=True, timeout=120,
                          check=True)
    lines = dict(line.split(" ", 1) for line in proc.stdout.splitlines())
    assert set(lines) == {"port", "file"}, proc.stdout + proc.stderr
    assert "too many files are open" in lines["port"] and "cable" not in lines["port"], lines["port"]
    assert "ulimit -n" in lines["port"]
    assert "too many files open" in lines["file"] and "check the path" not in lines["file"], lines["file"]
