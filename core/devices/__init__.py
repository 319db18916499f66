"""Device layers: byte transports, the line protocol, simulators and the instrument base classes."""

from .instrument import Emit, Identity, Instrument, InstrumentState, Reporter, SerialInstrument, Status
from .protocol import LineClient, Reply
from .setpoint import SetStatus
from .simulator import CommandError, Delay, Lines, LineSimulator, SimulatedWorld, SimulatorServer
from .streaming import DeviceClock, StreamingInstrument, StreamSample
from .transport import PtyEndpoint, TcpEndpoint, TransportFaults, open_port

__all__ = [
    "CommandError", "Delay", "DeviceClock", "Emit", "Identity", "Instrument", "InstrumentState", "LineClient",
    "LineSimulator", "Lines", "PtyEndpoint", "Reply", "Reporter", "SerialInstrument", "SetStatus", "SimulatedWorld",
    "SimulatorServer", "Status", "StreamSample", "StreamingInstrument", "TcpEndpoint", "TransportFaults", "open_port",
]
