"""Run many ``mirrorlab`` commands through one long-lived process, each with a hang timeout.

``mirrorlab.core.cli.main`` is the code path of the console script; a worker process imports it
once and runs one command per request, with file descriptors 1 and 2 pointed at temporary files,
so that everything the command prints (Python or HDF5's C library) is captured like a
subprocess's output. A command that does not answer within its timeout is a hang: the worker is
killed and :class:`CliHang` is raised. Fast enough for hypothesis to run hundreds of commands.

Usage::

    with CliWorker() as cli:
        result = cli.run("session", "info", "file.h5", timeout=30)
        result.returncode, result.stdout, result.stderr

Each command runs in the working folder it is given (default: the repository); ``sites`` are put on
the worker's ``PYTHONPATH`` (third-party plugins installed for a test), so a worker serves one set
of sites. An exception that escapes ``main`` (``--debug`` re-raises) is printed as Python prints an
uncaught one and gives exit code 1, as for the console script.
"""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import tempfile
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent


class CliHang(AssertionError):
    """A command did not answer within its timeout (the worker was killed)."""


class CliWorker:
    """A worker process running ``mirrorlab`` commands in-process, one at a time."""

    def __init__(self, cwd: Path | None = None, sites: Sequence[Path] = ()) -> None:
        self.cwd = cwd or REPO
        self.sites = tuple(sites)
        self.proc: subprocess.Popen[str] | None = None

    def __enter__(self) -> CliWorker:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _start(self) -> subprocess.Popen[str]:
        if self.proc is None or self.proc.poll() is not None:
            env = dict(os.environ)
            # the repository first: the worker imports tests.cli_worker from it whatever the sites
            env["PYTHONPATH"] = os.pathsep.join([str(REPO), *map(str, self.sites), env.get("PYTHONPATH", "")]).rstrip(
                os.pathsep)
            self.proc = subprocess.Popen([sys.executable, "-m", "tests.cli_worker"], cwd=self.cwd, env=env,
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        return self.proc

    def run(self, *args: str, timeout: float, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
        """Run ``mirrorlab ARGS`` in ``cwd``; raises :class:`CliHang` if no answer within ``timeout`` s."""
        proc = self._start()
        assert proc.stdin is not None and proc.stdout is not None
        proc.stdin.write(json.dumps({"argv": list(args), "cwd": str(cwd or self.cwd)}) + "\n")
        proc.stdin.flush()
        ready, _, _ = select.select([proc.stdout], [], [], timeout)
        if not ready:
            self.close()
            raise CliHang(f"`mirrorlab {' '.join(args)}` did not answer within {timeout} s")
        line = proc.stdout.readline()
        if not line:  # the worker died (e.g. a crash inside the HDF5 library)
            code = proc.wait()
            self.proc = None
            raise AssertionError(f"`mirrorlab {' '.join(args)}` killed the process (exit {code})")
        reply = json.loads(line)
        return subprocess.CompletedProcess(["mirrorlab", *args], reply["rc"], reply["stdout"], reply["stderr"])

    def close(self) -> None:
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.kill()
            self.proc.wait()
            for stream in (self.proc.stdin, self.proc.stdout):
                if stream is not None:
                    stream.close()
            self.proc = None


def _serve() -> None:
    from mirrorlab.core.cli import main

    channel = os.fdopen(os.dup(1), "w")  # replies go here; fds 1 and 2 belong to the commands
    for line in sys.stdin:
        request = json.loads(line)
        argv = request["argv"]
        os.chdir(request["cwd"])
        # "replace": a damaged file's invalid UTF-8 (kept by h5py as surrogates) may be printed
        with tempfile.TemporaryFile("w+", errors="replace") as out, \
                tempfile.TemporaryFile("w+", errors="replace") as err:
            saved = os.dup(1), os.dup(2)
            os.dup2(out.fileno(), 1)
            os.dup2(err.fileno(), 2)
            try:
                rc = main(argv)
            except SystemExit as exc:  # argparse's --help and usage errors
                rc = exc.code if isinstance(exc.code, int) else 1
            except Exception:  # what --debug re-raises: printed as the interpreter prints it, exit 1
                traceback.print_exc()
                rc = 1
            finally:
                sys.stdout.flush()
                sys.stderr.flush()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
                os.close(saved[0])
                os.close(saved[1])
            out.seek(0)
            err.seek(0)
            channel.write(json.dumps({"rc": rc, "stdout": out.read(), "stderr": err.read()}) + "\n")
            channel.flush()


if __name__ == "__main__":
    _serve()
