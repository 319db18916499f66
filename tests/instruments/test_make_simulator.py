"""Every built-in instrument's ``make_simulator`` keeps the base class's signature
``(settings, seed, world=None)``, so any caller of the base (a session with a shared world, the
conformance kit, ``mirrorlab simulate``) can call any plugin's."""

from __future__ import annotations

import inspect

import pytest
from mirrorlab.core import get_registry
from mirrorlab.core.devices import Instrument, LineSimulator

BASE = inspect.signature(Instrument.make_simulator)


@pytest.mark.parametrize("name", get_registry().names("instrument"))
def test_make_simulator_takes_the_base_signature(name: str) -> None:
    cls = get_registry().instrument(name)
    assert inspect.signature(cls.make_simulator).parameters.keys() == BASE.parameters.keys()
    model = cls.make_simulator(cls.parameters.defaults(), seed=0, world=None)
    assert isinstance(model, LineSimulator) and model.kind == cls.kind
