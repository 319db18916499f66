"""What the simulators' device models share besides the world (:mod:`.world`): their noise generator and
the answer to a ``SIM:FAULT`` with the wrong number of arguments.

:class:`SeededNoise` gives a :class:`~mirrorlab.core.devices.LineSimulator` model one numpy generator,
seeded with the simulator's seed and re-seeded by ``SIM:SEED``, so that the same seed and command
sequence give the same replies. :func:`fault_usage` is the ``E02`` reply naming a fault's arguments.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np

__all__ = ["SeededNoise", "fault_usage"]


class SeededNoise:
    """Mixin (before :class:`~mirrorlab.core.devices.LineSimulator`) of a model whose random draws come from
    ``np_rng``, a numpy generator seeded with the simulator's ``seed`` and re-seeded by ``SIM:SEED``.

    Examples
    --------
    >>> from mirrorlab.core.devices import LineSimulator
    >>> class Noisy(SeededNoise, LineSimulator):
    ...     def cmd_DRAW_Q(self, args):
    ...         yield f"OK {self.np_rng.integers(1000)}"
    >>> a, b = Noisy(seed=7), Noisy(seed=7)
    >>> a.execute("DRAW?") == b.execute("DRAW?"), a.execute("SIM:SEED 7"), a.execute("DRAW?") == Noisy(7).execute("DRAW?")
    (True, ['OK'], True)
    """

    seed: int

    def __init__(self, seed: int = 0) -> None:
        self.np_rng = np.random.default_rng(seed)
        super().__init__(seed)  # type: ignore[call-arg]  # the LineSimulator after this mixin

    def cmd_SIM_SEED(self, args: list[str]) -> Iterator[str]:
        yield from super().cmd_SIM_SEED(args)  # type: ignore[misc]
        self.np_rng = np.random.default_rng(self.seed)


def fault_usage(name: str, arguments: Sequence[str]) -> tuple[str, str]:
    """The ``(code, text)`` of the error answering ``SIM:FAULT <name>`` with other than one value per argument.

    Examples
    --------
    >>> fault_usage("RAIL", ("um", "period_mm"))
    ('E02', 'usage: SIM:FAULT RAIL <um> <period_mm>')
    """
    return "E02", f"usage: SIM:FAULT {name} {' '.join('<' + n + '>' for n in arguments)}"
