"""Controllers: live logic between streams and instruments, such as a closed control loop.

A controller is the third plugin kind, next to instruments and algorithms. It declares

* ``inputs``: the stream roles it subscribes to (bound to ``"<instrument>/<stream>"`` when added);
* ``commands``: the instrument roles it commands and, per role, the live-settable parameters it
  sets (bound to instrument labels when added);
* :meth:`streams`: anything else it outputs.

The session starts a controller after its instruments and stops it before them, runs it in a
supervised thread of its own and records what it did under ``/controllers/<label>/``: every
set-point it sent (one stream per commanded parameter, ``<role>.<parameter>``), the latency from
the input sample that caused it to the device's acknowledgement (``latency``, s) and its own
streams. A controller that raises is reported (``controller_failed``) and every instrument it
commands is told to :meth:`~mirrorlab.core.devices.Instrument.hold`::

    class Follow(Controller):
        name = "follow"
        version = "1.0.0"
        description = "Point an actuator at the angle a sensor reports"
        inputs = {"angle": "angle to follow, rad"}
        commands = {"actuator": ("target",)}

        def on_block(self, role, block, ctx):
            ctx.set("actuator", "target", float(block.values[-1]), sample_time=float(block.times[-1]))

Units: session time in seconds, latencies in seconds, set-point values in the commanded
parameter's API unit (millimetres, radians...).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

from .params import ParameterSet
from .streams import StreamSpec

if TYPE_CHECKING:
    from .controller_runtime import ControllerContext
    from .streams import Block


class Controller(ABC):
    """Base class of every controller plugin.

    Parameters
    ----------
    label
        The controller's name in the session (HDF5 group ``/controllers/<label>``).
    settings
        Values for :attr:`parameters`; validated at construction.
    """

    name: ClassVar[str]
    version: ClassVar[str]
    description: ClassVar[str]
    parameters: ClassVar[ParameterSet] = ParameterSet()
    #: Input role -> what the stream must be (one line, with its unit).
    inputs: ClassVar[Mapping[str, str]] = {}
    #: Commanded instrument role -> names of the live-settable parameters the controller sets.
    commands: ClassVar[Mapping[str, tuple[str, ...]]] = {}
    #: Hand :meth:`on_block` only the newest waiting block of each input (a loop that fell behind
    #: catches up instead of replaying stale samples); ``False``: every block, in order (a filter).
    latest_only: ClassVar[bool] = False

    def __init__(self, label: str, settings: Mapping[str, Any] | None = None) -> None:
        self.label = label
        self.settings: dict[str, Any] = self.parameters.validate(dict(settings or {}),
                                                                 where=f"controllers.{label}.settings")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.label!r}>"

    def commanded(self) -> Mapping[str, tuple[str, ...]]:
        """Role -> live parameters this instance sets (default: :attr:`commands`; a controller whose
        parameter names come from its settings overrides it)."""
        return self.commands

    def streams(self) -> list[StreamSpec]:
        """Streams this controller emits besides its set-points and latency (default: none)."""
        return []

    def setup(self, ctx: ControllerContext) -> None:
        """Called in the controller's thread before the first block (default: nothing)."""
        return None

    @abstractmethod
    def on_block(self, role: str, block: Block, ctx: ControllerContext) -> None:
        """React to one block of the input bound to ``role``: compute, then ``ctx.set(...)``.

        Runs in the controller's thread; blocks arrive in the order they were published.
        """

    def teardown(self, ctx: ControllerContext) -> None:
        """Called in the controller's thread after the last block (default: nothing)."""
        return None
