"""Batch re-processing on Dask distributed: many session files, and long recordings in chunks of frames.

* :mod:`.cluster`: a Dask client on a ``LocalCluster`` (default) or a running scheduler.
* :mod:`.chunks`: pure functions splitting frames into chunks and merging chunk outputs in frame order.
* :mod:`.executors`: what :attr:`Session.executor <mirrorlab.core.session.Session.executor>` runs
  algorithms with: in this process noting where (a batch task), or in chunks of frames on workers.
* :mod:`.runner`: one batch task per session file (copy, analysis recipe, key figures), retries and the summary.
* :mod:`.cli`: ``mirrorlab batch``; :mod:`.options`: the ``--workers`` / ``--scheduler`` options.

Nothing here is imported by ``mirrorlab --help``; Dask is imported only when a cluster is started.
"""
