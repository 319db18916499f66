"""Built-in instrument plugins; each sub-package is one instrument with its simulator, and its
``plugin.py`` (an entry point of its own) registers it.

``virtual_lab`` is not an instrument: it is the shared simulation, what several simulators use,
importing only the core: the simulated experiment (scenes, camera, mirrors, renderer, ground truth
with its own optics and motion models) that the simulators film, the tracking world, the line
sensor of the line tracker and the gimbal, and the trackers' experiment and report helpers. It
knows nothing of the instruments, and no instrument imports another (``docs/ARCHITECTURE.md``,
"Dependency rules"). The film scanner's
:mod:`~mirrorlab.instruments.film_scanner.virtual` films it, and its plugin stores the truth of
every recording made on it under ``/truth/<instrument>``; the virtual lab's plugin stores that of a
session's shared tracking world under ``/truth/world`` (:mod:`.virtual_lab.worlds`).
"""

