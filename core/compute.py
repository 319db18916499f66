"""Algorithm runs of a session: inputs resolved and read, computed, stored with provenance.

:class:`Compute` resolves each input (a dataset path, an ``@label/output`` or ``@algorithm/output``
reference, or an array), runs the algorithm through :func:`~mirrorlab.core.algorithms.execute` in
this process or through the session's :attr:`~Compute.executor` (e.g. chunks of frames on Dask
workers, :mod:`mirrorlab.core.batch.executors`) while the file is shared for reading (SWMR), and
has the :class:`~mirrorlab.core.store.session_file.SessionFile` store the run.

:class:`~mirrorlab.core.session.Session` is its public face; the parameters are documented here.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from .algorithms import Algorithm, AlgorithmExecutor, ResultRef, RunContext, execute, label_problem
from .clock import utc_now_iso
from .digests import read_hashed
from .errors import Problem, ValidationError

if TYPE_CHECKING:
    from .runtime import DeviceRuntime, Notify
    from .session import Session
    from .store.session_file import SessionFile


class Compute:
    """Runs algorithms for ``session`` (whose file is ``store`` and whose ``runtime`` holds the stop
    event); ``notify`` calls the lifecycle hook ``mirrorlab_result_written``."""

    def __init__(self, session: Session, store: SessionFile, runtime: DeviceRuntime, notify: Notify) -> None:
        self.session = session
        self.store = store
        self.runtime = runtime
        self.notify = notify
        #: Runs algorithms for :meth:`run` instead of this process (see :mod:`mirrorlab.core.batch`):
        #: called as ``executor(session, cls, inputs, params, context)`` with inputs as
        #: :class:`~mirrorlab.core.store.reader.StoredArray` datasets or arrays, returns the
        #: ``RunOutcome`` and each input's digest entry (:func:`~mirrorlab.core.digests.input_entry`);
        #: its ``provenance`` dict is stored as ``@executor``.
        self.executor: AlgorithmExecutor | None = None

    def run(self, algorithm: str | type[Algorithm], inputs: Mapping[str, str | np.ndarray],
            parameters: Mapping[str, Any] | None = None,
            progress: Callable[[float, float | None, str], None] | None = None, *,
            label: str | None = None, input_units: Mapping[str, str] | None = None) -> ResultRef:
        """Run an algorithm and store its result with provenance.

        Parameters
        ----------
        algorithm
            Registered name or class.
        inputs
            Input name → dataset path in this file (``"/instruments/cam/frames/data"``), result
            reference (``"@algorithm/output"``, ``"@label/output"``, see :meth:`resolve`) or array.
        parameters
            Algorithm parameters (validated; defaults filled in and stored).
        progress
            Optional ``progress(done, total, message)`` callback (progress events are emitted too).
        label
            Run label (``as = "..."`` in a recipe's ``run`` step) so that ``@label/output`` names
            this run's output even after later runs of the same algorithm. At most one successful
            run of a session carries a label; see :func:`~mirrorlab.core.algorithms.label_problem`.
        input_units
            Input name → unit of an input given as an array (or as a dataset without a ``unit``
            attribute). An output unit declared as ``{name}/s`` becomes ``mm/s`` when input
            ``name`` is in ``mm``; a dataset's own unit takes precedence.

        Returns the :class:`ResultRef`. The run is written as ``/results/<algorithm>/<run-id>``:
        its outputs first, each with the ``unit`` and ``description`` of its declared
        :class:`~mirrorlab.core.algorithms.Port`, and its ``status`` last, so a run whose writing was
        interrupted has no status and reads as ``incomplete``. A failed run is stored with
        ``status = "failed"`` and its error, a run stopped by ``Session.request_stop`` with
        ``status = "cancelled"``; neither has outputs, and nothing earlier is overwritten.
        """
        store, events = self.store, self.store.events
        store.require_writable("write results")
        cls = self.session.registry.algorithm(algorithm) if isinstance(algorithm, str) else algorithm
        label = label or ""
        if label:
            self.check_label(label, f"{cls.name}.label")
        arrays, sources, units = {}, {}, {}
        for name, value in inputs.items():
            if isinstance(value, str):
                sources[name] = self.resolve(value, f"inputs.{name}")
                units[name] = store.unit_of(sources[name])
            else:
                arrays[name] = np.asarray(value)
        for name, unit in (input_units or {}).items():
            if name in inputs and not units.get(name):
                units[name] = unit
        datasets = dict(sources)

        def report(done: float, total: float | None, message: str) -> None:
            events.progress(cls.name, done, total, message)
            if progress is not None:
                progress(done, total, message)

        store.commit()
        started = utc_now_iso()
        # While the inputs are read and the algorithm runs, the file is in SWMR mode: if this process
        # is killed then, the file opens through SWMR and `session close` repairs it (killed outside
        # SWMR mode, it would need HDF5's h5clear tool). Outputs are written after, in normal mode.
        # request_stop() cancels the run at its next progress report.
        with self.runtime.operation(), store.shared_for_reading(required=False):
            # Datasets are opened only now (HDF5 cannot enter SWMR mode while an object written in an
            # older format is open); read here, or in chunks by the executor's workers.
            read = {name: store.stored_array(datasets[name]) if name in datasets else arrays[name] for name in inputs}
            context = RunContext(report, self.runtime.cancel)
            if self.executor is None:
                values, digests = read_hashed(read)
                outcome = execute(cls, values, parameters or {}, context)
            else:  # the executor hashes the inputs as it reads them
                outcome, digests = self.executor(self.session, cls, read, parameters or {}, context)
            sources.update({name: f"sha256:{digests[name]['sha256']}" for name in read if name not in sources})
        ref = store.write_result(cls, label, started, outcome, sources, digests, units,
                                 None if self.executor is None else self.executor.provenance)
        events.emit({"ok": "info", "cancelled": "warning"}.get(outcome.status, "error"), cls.name,
                    "result_written", f"{ref.path}{f' ({label})' if label else ''}: {outcome.status}"
                    f"{' — ' + outcome.error if outcome.error else ''}", label=label)
        store.write_log()
        store.flush()
        self.notify("mirrorlab_result_written", result=ref)
        return ref

    def check_label(self, label: str, key: str) -> None:
        """Raise :class:`ValidationError` unless ``label`` can name a new successful run."""
        reason = label_problem(label, {*self.session.registry.names("algorithm"), *self.store.members("results")})
        taken = [r for r in self.store.results() if r.label == label and r.status == "ok"]
        if reason is None and taken:
            reason = f"label {label!r} already names {taken[0].path}; choose another label"
        if reason is not None:
            raise ValidationError([Problem(key, reason)])

    def resolve(self, reference: str, key: str = "dataset") -> str:
        """The dataset path a reference names (``key``: the recipe or CLI key in errors).

        ``/absolute/path`` names itself; ``@name/output`` names ``output`` of the successful run
        labelled ``name`` if there is one, else of the latest successful run of the algorithm
        ``name`` in this session (how recipe steps chain results).
        """
        store = self.store
        if not reference.startswith("@"):
            path = reference
        else:
            name, _, output = reference[1:].partition("/")
            runs = [r for r in store.results() if r.status == "ok" and name in (r.label, r.algorithm)]
            labelled = [r for r in runs if r.label == name]
            run = (labelled or runs)[-1] if runs else None
            if run is None or not output:
                raise ValidationError([Problem(key, f"{reference!r}: no successful run of {name!r} (an algorithm "
                                               "or a run label) in this session yet (write @algorithm/output "
                                               "or @label/output after its step)")])
            path = f"{run.path}/{output}"
            outputs = store.members(run.path)
            if output not in outputs:
                raise ValidationError([Problem(key, f"{reference!r}: {run.path} has no output {output!r}; it has: "
                                               f"{', '.join(outputs) or 'none'}")])
        if not store.exists(path) or not store.node(path).is_dataset:
            raise ValidationError([Problem(key, f"no dataset {path!r} in {store.path}")])
        return path
