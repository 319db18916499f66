"""What every Dask worker of a mirrorlab batch sets up before its first task (imports ``distributed``:
loaded only with a cluster)."""

from __future__ import annotations

from distributed import Worker, WorkerPlugin


class OneLibraryThread(WorkerPlugin):
    """OpenCV's own thread pool off in each worker: a task runs on one core and the cluster's workers
    are the parallelism, as Dask's ``OMP_NUM_THREADS=1`` intends (OpenCV's pool does not read it).
    Otherwise each worker's detection spreads over every core and the workers crowd each other out.
    """

    name = "mirrorlab-one-library-thread"

    def setup(self, worker: Worker) -> None:
        import cv2

        cv2.setNumThreads(1)
