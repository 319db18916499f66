"""The multistart fallback (spec §6) off the real-time path: a worker process.

:class:`FallbackWorker` runs :meth:`.Tracker.fallback` (a multistart of about 9 LM solves, 20–40 ms
of CPU) in a separate Python process, one job at a time, so the streaming filter's compute module
publishes the warm-started solution on time and adopts the multistart's result on a later frame
(:class:`.stream.Compute`).

Why a process, not a thread: the multistart is hundreds of numpy calls on arrays of a few dozen
numbers, so it runs almost entirely holding the GIL (where numpy releases the GIL inside a call,
that call's few microseconds are mostly argument handling and dispatch, which hold it). A worker
thread would take the GIL from the compute, input and output threads in slices of
``sys.getswitchinterval()`` (5 ms) while it runs, against an 8.3 ms deadline at 120 Hz; a process
has its own interpreter and competes only for a CPU core (``benchmarks/bench_retarget.py``
measures both, docs/retarget.md has the figures). And a process can be given a lower CPU priority
(:data:`WORKER_NICE`): on a busy machine the multistart then takes only spare CPU time and
finishes later, instead of slowing the real-time path; a thread's priority cannot lower its claim
on the GIL.

Why a plain subprocess, not :mod:`multiprocessing`: its ``spawn`` and ``forkserver`` children
re-import the caller's main script (an unguarded script would run again), and ``fork`` is unsafe
once the filter's threads run. The child runs this module (``python -m``) and talks through two
:class:`multiprocessing.connection.Connection` pipes (pickled messages). It exits when the parent
closes the job pipe, also when the parent dies.

Units: mm, rad; f mm².
"""

from __future__ import annotations

import os
import subprocess
import sys
from multiprocessing.connection import Connection, Pipe

import numpy as np
from numpy.typing import NDArray

from .approximate import Tracker
from .errors import RetargetError
from .objective import Arms
from .solvers import Solution

__all__ = ["FallbackWorker"]

FloatArray = NDArray[np.float64]

#: Seconds the worker may take to start (import numpy and this package).
START_TIMEOUT_S = 120.0
#: Niceness the worker adds to its own: it is best-effort work beside a real-time loop.
WORKER_NICE = 10


class FallbackWorker:
    """A worker process that runs the tracker's multistart for one row at a time.

    Parameters
    ----------
    tracker : Tracker
        Sent to the worker once (objective, start points): the same multistart as a synchronous
        :meth:`.Tracker.fallback`, to the bit.

    Raises
    ------
    RetargetError
        The worker did not start within :data:`START_TIMEOUT_S` or exited.

    Examples
    --------
    >>> import numpy as np
    >>> from mirrorlab.plugins.retarget import Chain, Objective, Tracker, correspondence_pairs
    >>> from mirrorlab.plugins.retarget.correspondence import serial_parents
    >>> inp, out = Chain([1, 1, 1, 1], ["z", "y", "z", "y"]), Chain([2, 2], ["z", "y"])
    >>> obj = Objective(out, correspondence_pairs(serial_parents(5), inp.lengths, out), serial_parents(5))
    >>> arms = obj.arms(inp.forward([[0.4, -0.3, 0.5, 0.2]]))
    >>> with FallbackWorker(Tracker(obj)) as worker:
    ...     worker.submit(arms, np.eye(3), np.zeros(3), np.zeros((1, 2)))
    ...     round(float(worker.result().f[0]), 6)                     # spec T1: f* (mm²)
    0.28254
    """

    def __init__(self, tracker: Tracker) -> None:
        job_r, self._jobs = Pipe(duplex=False)
        self._results, res_w = Pipe(duplex=False)
        self._proc = subprocess.Popen([sys.executable, "-m", __name__, str(job_r.fileno()), str(res_w.fileno())],
                                      stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                      pass_fds=(job_r.fileno(), res_w.fileno()))
        job_r.close()          # the child's ends: closed here, so the child's exit is seen as EOF
        res_w.close()
        self.busy = False
        try:
            self._jobs.send(tracker)
            if not self._results.poll(START_TIMEOUT_S):
                raise RetargetError(f"the multistart worker process did not start within {START_TIMEOUT_S:g} s; "
                                    "the machine may be overloaded")
            self._receive()
        except BaseException:
            self.close()
            raise

    def submit(self, arms: Arms, R_b: FloatArray, p_b: FloatArray, warm: FloatArray) -> None:
        """Start the multistart of one row (arms of 1 row, base (3, 3) and (3,) or (1, 3) mm, warm (1, dof) rad)."""
        if self.busy:
            raise RetargetError("the multistart worker is busy: take its result before submitting another row")
        try:
            self._jobs.send((arms, R_b, p_b, warm))
        except OSError:                        # the worker has gone: its end of the pipe is closed
            raise RetargetError(f"the multistart worker process exited (code {self._proc.wait()}); "
                                "its error is on stderr") from None
        self.busy = True

    def ready(self) -> bool:
        """True when the submitted multistart has finished (never blocks)."""
        return self.busy and self._results.poll()

    def result(self) -> Solution:
        """The submitted multistart's solution (1 row), waiting for it if it is still running."""
        if not self.busy:
            raise RetargetError("no multistart was submitted to the worker")
        self.busy = False
        return self._receive()

    def _receive(self) -> Solution:
        try:
            return self._results.recv()
        except EOFError:
            code = self._proc.wait()
            raise RetargetError(f"the multistart worker process exited (code {code}); its error is on stderr") from None

    def close(self) -> None:
        """Stop the worker (it exits when its job pipe closes) and wait for it."""
        self._jobs.close()
        self._results.close()
        try:
            self._proc.wait(timeout=10.0)
        except subprocess.TimeoutExpired:       # still inside a multistart: it would only finish and exit
            self._proc.kill()
            self._proc.wait()

    def __enter__(self) -> FallbackWorker:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _serve(jobs: Connection, results: Connection) -> None:
    """The worker's loop: receive the tracker, then one multistart per job, until the job pipe closes."""
    os.nice(WORKER_NICE)
    tracker: Tracker = jobs.recv()
    results.send(None)                         # ready
    while True:
        try:
            arms, R_b, p_b, warm = jobs.recv()
        except EOFError:
            return
        try:
            results.send(tracker.fallback(arms, R_b, p_b, warm))
        except BrokenPipeError:                # the parent closed while this multistart ran: discarded
            return


if __name__ == "__main__":
    _serve(Connection(int(sys.argv[1]), writable=False), Connection(int(sys.argv[2]), readable=False))
