"""Every simulator against the line protocol its page documents, both ways: any input at all leaves it
answering (served, in raw bytes), every command counts its arguments, integers and numbers are read as
the pages name them, the pages list exactly the commands the simulators take, and no stream line
follows the ``OK`` of ``STREAM OFF``."""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from mirrorlab.core.devices import LineSimulator, SimulatorServer
from mirrorlab.instruments.film_scanner.model import FilmScannerModel
from mirrorlab.instruments.line_tracker.model import LineTrackerModel
from mirrorlab.instruments.mirror_gimbal.model import MirrorGimbalModel
from mirrorlab.instruments.reference import ChainSource
from mirrorlab.instruments.reference.models import ActuatorModel, AngleSourceModel
from mirrorlab.instruments.ultrasonic_tracker.acoustics import PITCH, wavenumber
from mirrorlab.instruments.ultrasonic_tracker.model import UltrasonicTrackerModel
from mirrorlab.instruments.virtual_lab.line_sensor.detector import OpticalDetector

from tests.raw_line import RawClient
from tests.support import REPO

MODELS: dict[str, Callable[[], LineSimulator]] = {
    "angle_source": AngleSourceModel,
    "actuator": ActuatorModel,
    "chain_source": lambda: ChainSource.make_simulator({}, 0),
    "film_scanner": FilmScannerModel,
    "ultrasonic_tracker": UltrasonicTrackerModel,
    "line_tracker": LineTrackerModel,
    "mirror_gimbal": MirrorGimbalModel,
}
PAGES = {"angle_source": "reference.md", "actuator": "reference.md", "chain_source": "reference.md",
         "film_scanner": "film_scanner.md", "ultrasonic_tracker": "ultrasonic_tracker.md",
         "line_tracker": "line_tracker.md", "mirror_gimbal": "mirror_gimbal.md"}

COMMON = ["*IDN?", "PING", "*RST", "STAT?", "TIME?", "STREAM OFF", "ERR?", "ABORT", "SIM:SEED 3", "SIM:CLOCK FAST",
          "SIM:FAULT CLEAR", "SIM:FAULT?", "SIM:TRUTH?"]
DETECTOR = ["CLK 6500", "THR 128", "THR?", "FRAME?", "GREY?", "MARK?", "RUNS?", "AUTO ON 2 60", "SELECT WIDEST",
            "STREAM OFF"]
#: One well-formed use of every command of each simulator (the coverage test keeps it complete).
VALID: dict[str, list[str]] = {
    "angle_source": [*COMMON, "RATE 50", "WAVE 200000 0.5"],
    "actuator": [*COMMON, "RATE 50", "SPEED 2000000", "TGT 1000", "TGT?", "HOLD", "POS?"],
    "chain_source": [*COMMON, "RATE 50", "JOINTS?", "SEL shoulder elbow", "SEL?", "FRAMES?", "SEEK 3"],
    "film_scanner": [*COMMON, "SIM:FAULT RAIL 5 25", "CLK 73000", "THR 128", "THR?", "HEADTHR 128 128 37",
                     "CLAMP BASE", "HOME", "FEED 2", "STEP 10", "HEAD", "LINE?", "GREY?", "SCAN 2", "POS?"],
    "ultrasonic_tracker": [*COMMON, "SIM:FAULT TEMP 20", "SIM:LOAD STILL 0 6 1300", "AIM 1 -2", "AIM?", "PSI 45",
                           "BEAM A", "EMIT", "IDENT", "MEAS?", "STEP 2.5 200", "RAND 12 18", "TRACK OFF"],
    "line_tracker": [*COMMON, "SIM:FAULT TWOPEAK 8 0.9", "SIM:LOAD STILL 0 3000", *DETECTOR],
    "mirror_gimbal": [*COMMON, "SIM:FAULT BACKLASH H 0.5", "SIM:LOAD STILL 4 0 3000", "MODE H TRACK", "POS V 2.5",
                      "ANG? H", "SENS? H", "GAIN H 1", "LIMIT H -30 30", "DEADBAND H 0",
                      *(f"{axis}:{c}" for axis in "HV" for c in DETECTOR)],
}
VARIADIC = {"SEL"}   # SEL <joint> [<joint> ...]: one more argument is one more joint


def command_word(handler: str) -> str:
    """The command word of a handler name (``cmd_SIM_FAULT_Q`` -> ``SIM:FAULT?``, ``cmd_RST`` -> ``*RST``)."""
    name = handler[len("cmd_"):]
    word = name[:-2] + "?" if name.endswith("_Q") else name
    return ("*" if handler in ("cmd_IDN_Q", "cmd_RST") else "") + word.replace("_", ":")


def handled_words(model: LineSimulator) -> set[str]:
    """Every command word the model takes (a detector's under its host's prefixes)."""
    words = {command_word(n) for n in dir(model) if n.startswith("cmd_")}
    detector = {command_word(n) for n in dir(OpticalDetector()) if n.startswith("cmd_")}
    if isinstance(model, LineTrackerModel):
        words |= detector
    if isinstance(model, MirrorGimbalModel):
        words |= {f"{axis}:{w}" for axis in "HV" for w in detector}
    return words


@pytest.mark.parametrize("name", MODELS)
def test_the_table_of_valid_commands_covers_every_command(name: str) -> None:
    assert {c.split()[0] for c in VALID[name]} == handled_words(MODELS[name]())


@pytest.mark.parametrize(("name", "command"), [(n, c) for n, cs in VALID.items() for c in cs])
def test_a_command_takes_its_documented_arguments_and_not_one_more(name: str, command: str) -> None:
    model = MODELS[name]()
    model.fast = True
    reply = model.execute(command)[-1]
    assert not reply.startswith(("ERR E01", "ERR E02")), (command, reply)
    if command.split()[0] not in VARIADIC:
        assert model.execute(command + " x")[-1].startswith("ERR E02 "), command



# -- integer arguments: exactly those each page lists ---------------------------------------------------------
#: Well-formed uses of the commands whose integer arguments only a fault names (beside :data:`VALID`).
MORE_EXAMPLES: dict[str, list[str]] = {
    "ultrasonic_tracker": ["SIM:FAULT SERVOGAIN 1 0.5"],
    "line_tracker": ["SIM:FAULT BACKGROUND 1 10", "SIM:FAULT MULTI 2"],
    "mirror_gimbal": ["SIM:FAULT BACKGROUND 1 10", "SIM:FAULT MULTI 2"],
}
NOT_AN_INTEGER = re.compile(r"ERR E02 ([A-Z]+: )?not an integer: 1\.5")
NUMERIC = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")


def listed_integer_arguments(name: str) -> list[str]:
    """The syntaxes the page of simulator ``name`` lists after ``Integer arguments:`` (on a page of several
    devices, in the section whose heading names its kind); every ``<...>`` in them is an integer."""
    text = (REPO / "docs" / "instruments" / PAGES[name]).read_text()
    sections = [part for part in re.split(r"(?m)^(?=## )", text) if "\nInteger arguments: " in part]
    if len(sections) > 1:
        sections = [part for part in sections if MODELS[name]().kind in part.splitlines()[0]]
    (section,) = sections
    (line,) = re.findall(r"(?m)^Integer arguments: (.*)$", section)
    return re.findall(r"`([^`]+)`", line.split(";")[0])


def integer_positions(name: str) -> list[tuple[str, int]]:
    """(example command, index of an integer word in it) for every argument the page lists as an integer."""
    examples = VALID[name] + MORE_EXAMPLES.get(name, [])
    found = []
    for syntax in listed_integer_arguments(name):
        words = syntax.split()
        prefix = [w.upper() for w in words if not w.startswith("<")]
        assert prefix == [w.upper() for w in words[:len(prefix)]], syntax   # the integers after the words
        example = next((c for c in examples if [w.upper() for w in c.split()[:len(prefix)]] == prefix
                        and len(c.split()) >= len(words)), None)
        assert example is not None, f"{PAGES[name]}: no example of {syntax!r} to try"
        found += [(example, i) for i in range(len(prefix), len(words))]
    return found


def with_word(command: str, index: int, word: str) -> str:
    words = command.split()
    return " ".join([*words[:index], word, *words[index + 1:]])


def reply_to(name: str, command: str) -> str:
    model = MODELS[name]()
    model.fast = True
    return model.execute(command)[-1]


@pytest.mark.parametrize("name", MODELS)
def test_the_integer_arguments_a_page_lists_refuse_a_decimal(name: str) -> None:
    """Each argument under *Integer arguments* answers ``1.5`` with ``ERR E02 not an integer``; every other
    numeric argument of the examples takes it as a number (perhaps out of range, never "not an integer")."""
    integers = integer_positions(name)
    assert any(c.startswith("SIM:SEED") for c, _ in integers), "SIM:SEED <n> is every simulator's integer"
    for command, index in integers:
        reply = reply_to(name, with_word(command, index, "1.5"))
        assert NOT_AN_INTEGER.fullmatch(reply), (with_word(command, index, "1.5"), reply)
    for command in VALID[name] + MORE_EXAMPLES.get(name, []):
        for index, word in enumerate(command.split()):
            if index and NUMERIC.fullmatch(word) and (command, index) not in integers:
                reply = reply_to(name, with_word(command, index, "1.5"))
                assert "not an integer" not in reply, (f"{PAGES[name]} does not list it as an integer",
                                                       with_word(command, index, "1.5"), reply)


# -- served: any bytes, and the end of a stream -------------------------------------------------------------
NUMBERS = ["0", "-1", "1.5", "1e9", "-0", "nan", "inf", "99999999999999999999", "0x10", "1_000", "+7", ".", "1e6",
           "-1e6", "90", "-40", "344"]
WORDS = sorted({w for commands in VALID.values() for c in commands for w in c.split()} - {"SIM:CLOCK"})  # FAST stays
TOKEN = st.one_of(st.sampled_from(NUMBERS + WORDS).map(str.encode), st.binary(max_size=4))


@st.composite
def mistaken(draw: st.DrawFn) -> bytes:
    """A documented command with arguments replaced, and some added: what a client may get wrong."""
    words = draw(st.sampled_from([c for commands in VALID.values() for c in commands])).split()
    args = [draw(st.one_of(st.just(a.encode()), TOKEN)) for a in words[1:]]
    return b" ".join([words[0].encode(), *args, *draw(st.lists(TOKEN, max_size=2))])


INPUT = st.one_of(st.binary(max_size=400), st.lists(st.one_of(mistaken(), st.binary(max_size=20)), max_size=5)
                  .map(b"\n".join))
MARK = b"NOSUCH4711"   # the line after the input: its error marks where the input's replies end
TERMINAL = re.compile(r"OK( .*)?|ERR E\d\d .*")
REPLY_LINE = re.compile(r"OK( .*)?|ERR E\d\d .*|![A-Z].*|[A-Z][A-Z0-9:]* .*")


@settings(max_examples=100, deadline=None)
@given(data=INPUT)
@example(data=b"\xff")
@example(data=b"PING\xff")
@example(data="PÏNG".encode())
@example(data=b"PIN")
@example(data=b"WAVE 1")
@example(data=b"TGT")
@example(data=b"SPEED")
@example(data=b"RATE 5")
@example(data=b"SIM:LOAD STILL 0 0\nSIM:LOAD STILL 0 0 0\nSIM:TRUTH?\nEMIT")
@example(data=b"SIM:FAULT TEMP -1000\nPSI 45")
@example(data=b"\x18\x18PI\x18")
@example(data=b"X" * 5000)
@pytest.mark.parametrize("name", MODELS)
def test_any_bytes_leave_the_simulator_answering_ping(name: str, data: bytes) -> None:
    """Whatever comes first, PING then answers ``OK PONG``: every line before it is printable ASCII of the
    protocol's shapes, at most one terminal line per line sent (or abort byte), never an internal error."""
    model = MODELS[name]()
    model.fast = True
    with SimulatorServer(model, "tcp") as server, RawClient(server.url) as c:
        c.send(data + b"\n" + MARK + b"\nPING\n")
        lines = []
        while (line := c.line()) != f"ERR E01 unknown command {MARK.decode()}":
            lines.append(line)
        assert c.reply() == ["OK PONG"]
        time.sleep(0.01)   # the clock runs on: what the input set up is simulated for a while
        assert c.ask("PING") == ["OK PONG"]
    assert all(REPLY_LINE.fullmatch(line) for line in lines), lines
    terminal = [line for line in lines if TERMINAL.fullmatch(line)]
    assert len(terminal) <= data.count(b"\n") + data.count(b"\x18") + 1, terminal
    assert not any(line.startswith(("ERR E99", "!ERR E99")) for line in lines), lines


STREAMS = {"angle_source": ["RATE 200", "STREAM ON"], "actuator": ["RATE 200", "STREAM ON"],
           "chain_source": ["RATE 200", "STREAM ON"], "ultrasonic_tracker": ["STREAM ON", "TRACK ON"],
           "line_tracker": ["STREAM ON"], "mirror_gimbal": ["STREAM ON", "H:STREAM ON"]}


@pytest.mark.parametrize("name", STREAMS)
def test_no_stream_line_follows_the_ok_of_stream_off(name: str) -> None:
    with SimulatorServer(MODELS[name](), "tcp") as server, RawClient(server.url) as c:
        for command in STREAMS[name]:
            assert c.ask(command)[0].startswith("OK")
        seen = 0
        while seen < 3:
            seen += c.line().startswith("!")
        c.send(b"STREAM OFF\n" + (b"H:STREAM OFF\n" if name == "mirror_gimbal" else b""))
        for _ in range(2 if name == "mirror_gimbal" else 1):
            while (line := c.line()) != "OK":
                assert line.startswith("!"), line
        after = b""
        end = time.monotonic() + 0.4      # longer than a search cycle (80 ms) or a scan (78.8 ms)
        while time.monotonic() < end:
            after += c.read_some(0.05)
    assert [line for line in after.decode().splitlines() if not line.startswith("!ERR ")] == []


def test_the_ultrasonic_steering_phase_stays_within_its_documented_range() -> None:
    """PSI 0...90, quantised to 1.44 deg: 90 gives the last quantum inside the range, 89.28 deg."""
    model = UltrasonicTrackerModel()
    # delta = arcsin(2 psi / (sqrt(3) k d)) at the default 344 m/s, as the page gives it
    delta = math.degrees(math.asin(2 * math.radians(62 * 1.44) / (math.sqrt(3) * wavenumber(20.6) * PITCH)))
    assert model.execute("PSI 90") == [f"OK 89.28 {delta:.2f}"]
    assert model.execute("PSI 45") == ["OK 44.64 7.45"]
    assert model.execute("PSI 90.5")[0].startswith("ERR E03")


def test_no_reply_field_is_a_negative_zero() -> None:
    model = MirrorGimbalModel()
    model.fast = True
    assert model.execute("POS H -0.0004") == ["OK 0.000"]
    assert model.execute("POS H -0.0006") == ["OK -0.001"]


def test_samples_skipped_after_a_pause_are_counted_and_the_recording_plays_on() -> None:
    """A chain source 10 s behind at 100 frames/s sends the last 100 samples; the 901 before them are counted
    lost (the server says so in ``!OVF``) and their frames are skipped, not replayed later."""
    model = ChainSource.make_simulator({}, 0)
    assert model.execute("STREAM ON") == ["OK"]
    model.advance(10.0)
    lines = model.stream_lines()
    assert len(lines) == 100 and model.lost_lines == 901
    assert [int(line.split()[2]) for line in lines] == list(range(901, 1000)) + [0]   # a 1000-frame recording
