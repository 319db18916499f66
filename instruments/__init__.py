"""Built-in instrument plugins; each sub-package is one instrument with its simulator, and its
``plugin.py`` (an entry point of its own) registers it.

``virtual_lab`` is not an instrument: it is the simulated experiment (scenes, camera, mirrors,
renderer, ground truth) that the simulators film; it knows nothing of them. The film scanner's
:mod:`~mirrorlab.instruments.film_scanner.virtual` films it, and its plugin stores the truth of
every recording made on it under ``/truth/<instrument>``; the virtual lab's plugin stores that of a
session's shared tracking world under ``/truth/world`` (:mod:`.virtual_lab.worlds`).
"""

