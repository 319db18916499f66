"""FilmScannerModel: FSCAN protocol (§1.5), errors, abort, determinism, faults and the §1.4/§5
acceptance figures. Protocol tests run through a real pty (or TCP) with the real driver's client;
the repeatability acceptance drives the model in-process to keep the run short."""

from __future__ import annotations

import time
from collections.abc import Iterator

import cv2
import numpy as np
import pytest
from mirrorlab.core.devices import SimulatorServer, open_port
from mirrorlab.core.devices.wire import decode_bits
from mirrorlab.core.errors import DeviceReplyError
from mirrorlab.instruments.film_scanner import Film, FilmScanner, FilmScannerModel
from mirrorlab.instruments.film_scanner.film import PIXEL_MM
from mirrorlab.instruments.film_scanner.wire import PIXELS

from tests.tolerances import roundoff


@pytest.fixture
def scanner() -> Iterator[tuple[FilmScanner, SimulatorServer]]:
    with SimulatorServer(FilmScannerModel(seed=5), "pty") as server:
        dev = FilmScanner("fs", port=server.url, timeout=2.0)
        dev.connect()
        dev.simulate_query("SIM:CLOCK FAST")
        yield dev, server
        dev.close()


def code_of(dev: FilmScanner, command: str) -> str:
    with pytest.raises(DeviceReplyError) as info:
        dev.query(command)
    return info.value.code


def truth(dev: FilmScanner) -> dict[str, list[list[str]]]:
    out: dict[str, list[list[str]]] = {}
    for line in dev.simulate_query("SIM:TRUTH?").data:
        _, key, *rest = line.split(" ")
        out.setdefault(key, []).append(rest)
    return out




def blob_centres(image: np.ndarray, min_area: int = 40) -> np.ndarray:
    """Centroids (col, row) of the white blobs, sorted by column."""
    n, _, stats, centres = cv2.connectedComponentsWithStats((image > 0).astype(np.uint8))
    c = centres[1:][stats[1:, cv2.CC_STAT_AREA] >= min_area]
    return c[np.argsort(c[:, 0])]


# -- protocol ---------------------------------------------------------------------------------------
def test_identity_and_settings_commands(scanner: tuple[FilmScanner, SimulatorServer]) -> None:
    dev, _ = scanner
    assert dev.query("*IDN?").fields[0] == "FSCAN"
    assert dev.query("CLK 100000").fields == ["100000"]
    assert dev.query("THR 90").fields == ["90"] and dev.query("THR?").fields == ["90"]
    assert dev.query("HEADTHR 100 120 21").fields == []
    assert dev.query("STAT?").fields == ["IDLE", "NOHOME"]
    assert dev.query("POS?").fields == ["0", "0"]


def test_error_codes(scanner: tuple[FilmScanner, SimulatorServer]) -> None:
    dev, _ = scanner
    assert code_of(dev, "FROB") == "E01"
    assert code_of(dev, "THR") == "E02"
    assert code_of(dev, "CLAMP SIDEWAYS") == "E02"
    assert code_of(dev, "THR 256") == "E03"
    assert code_of(dev, "CLK 999") == "E03"
    assert code_of(dev, "CLK 400000") == "E03"           # host loop limit 307 692 Hz
    assert code_of(dev, "SCAN 345") == "E03"
    assert code_of(dev, "SCAN 10") == "E05"              # not homed
    assert code_of(dev, "SIM:FAULT RAIL 5") == "E02"
    assert code_of(dev, "SIM:FAULT GREMLIN 1") == "E03"
    assert dev.query("ERR?").fields[0] == "E03"
    dev.query("CLAMP BASE")
    assert int(dev.query("HOME").fields[0]) > 0
    assert code_of(dev, "FEED -1000") == "E06"           # left limit switch
    assert "LIMIT" in dev.query("STAT?").fields[1]


def test_home_fails_when_every_step_stalls(scanner: tuple[FilmScanner, SimulatorServer]) -> None:
    dev, _ = scanner
    dev.simulate_query("SIM:FAULT STALL 1")
    assert code_of(dev, "HOME") == "E06"


def test_head_reports_no_frame_at_the_end_of_the_film() -> None:
    film = Film.from_images([np.zeros((30, 40), np.uint8)])
    with SimulatorServer(FilmScannerModel(film, seed=1), "tcp") as server:
        dev = FilmScanner("fs", port=server.url)
        dev.connect()
        dev.simulate_query("SIM:CLOCK FAST")
        dev.prepare()
        lines, seconds = dev.head()
        assert lines > 37 and seconds > 0
        assert code_of(dev, "HEAD") == "E11"
        dev.close()


def test_line_grey_and_scan_replies(scanner: tuple[FilmScanner, SimulatorServer]) -> None:
    dev, _ = scanner
    line = dev.query("LINE?").data[0].split(" ")
    assert line[0] == "LINE" and len(line[2]) == 128 and len(decode_bits(line[2], PIXELS)) == 512
    dev.prepare()
    dev.head()
    reply = dev.query("SCAN 5")
    assert [d.split()[:2] for d in reply.data] == [["L", str(j)] for j in range(5)]
    assert reply.fields == ["5", "125"]                  # 5 x (7.0 ms read + 18 ms feed)
    assert dev.query("POS?").fields == ["4210", str(int(truth(dev)["POS"][0][3]))]
    grey = dev.grey_profile()
    assert grey.shape == (512,) and grey.max() < 40      # dark frame background (markers read > 200)


def test_abort_during_scan_keeps_lines_sent() -> None:
    with SimulatorServer(FilmScannerModel(seed=2), "pty") as server:
        port = open_port(server.url, timeout=0.05)
        try:
            port.write(b"SIM:CLOCK FAST\nCLAMP BASE\nHOME\nCLAMP CARRIER\nSIM:CLOCK REAL\nSCAN 200\n")
            time.sleep(0.5)                              # 200 lines take 5 s in real time
            port.write(b"\x18")
            data = b""
            deadline = time.monotonic() + 5
            while not data.endswith(b"ERR E09 aborted\nOK\n") and time.monotonic() < deadline:
                data += port.read(4096)
        finally:
            port.close()
    lines = data.decode().split("\n")
    scan = [l for l in lines if l.startswith("L ")]
    assert 3 <= len(scan) < 200
    assert [int(l.split()[1]) for l in scan] == list(range(len(scan)))
    assert lines[-3:] == ["ERR E09 aborted", "OK", ""]


@pytest.mark.parametrize("transport", ["pty", "tcp"])
def test_same_seed_same_bytes(transport: str) -> None:
    def session(seed: int) -> list[str]:
        with SimulatorServer(FilmScannerModel(seed=seed), transport) as server:
            dev = FilmScanner("fs", port=server.url)
            dev.connect()
            out = []
            for cmd in ("SIM:CLOCK FAST", "SIM:FAULT FILMNOISE 0.05", "CLAMP BASE", "HOME", "CLAMP CARRIER",
                        "HEAD", "SCAN 30", "GREY?", "SIM:TRUTH?"):
                reply = dev.query(cmd)
                out += reply.data + [" ".join(reply.fields)]
            dev.close()
            return out

    first, second, other = session(11), session(11), session(12)
    assert first == second
    assert first != other


# -- faults -----------------------------------------------------------------------------------------
def _homed_model(**faults: str) -> FilmScannerModel:
    model = FilmScannerModel(seed=3)
    model.execute("SIM:FAULT CLEAR")
    for name, value in faults.items():
        assert model.execute(f"SIM:FAULT {name} {value}") == ["OK"]
    for cmd in ("CLAMP BASE", "HOME", "CLAMP CARRIER"):
        assert model.execute(cmd)[-1].startswith("OK")
    return model


def _line_positions(model: FilmScannerModel, lines: int = 60) -> np.ndarray:
    model.execute("HEAD")
    model.execute(f"SCAN {lines}")
    return np.array([y for y, _ in model.last_scan])


def test_feedjitter_increases_along_feed_scatter() -> None:
    positions = _line_positions(_homed_model())
    ideal = np.diff(positions)[1:]
    jittery = np.diff(_line_positions(_homed_model(FEEDJITTER="8")))[1:]
    # whole steps of 4.6875 um: the positions (mm) differ by rounding only
    np.testing.assert_allclose(ideal, PIXEL_MM, rtol=0, atol=roundoff(scale=np.abs(positions).max(), ops=4))
    # ~8 um per line: the sd of 58 differences is good to 1 / sqrt(2 * 58) = 9 %; 4-12 um is +-5 sd
    assert 0.004 < jittery.std() < 0.012


def test_stall_loses_steps_and_backlash_loses_motion() -> None:
    model = _homed_model(STALL="0.2")
    film0 = model.carrier.film_um
    model.execute("FEED 100")
    moved = model.carrier.film_um - film0
    # 20 % of 1000 steps skipped: binomial sd 1.3 %, so 70-90 % is +-8 sd
    assert 0.7 * 4687.5 < moved < 0.9 * 4687.5

    model = _homed_model(BACKLASH="30")
    model.execute("FEED 20")
    before = model.carrier.film_um
    model.execute("FEED -20")
    # whole steps and the 30 um backlash, in um of up to ~1e5: rounding only
    assert before - model.carrier.film_um == pytest.approx(20 * 46.875 - 30, abs=roundoff(scale=abs(before), ops=4))


def test_vibration_and_rail_shift_lines_sideways() -> None:
    model = _homed_model(VIBRATION="20 5")
    model.execute("HEAD")
    model.execute("SCAN 40")
    dx = np.array([d for _, d in model.last_scan])
    # a 20 um sine sampled 8 times a period (40 lines, 1 s, 5 Hz) reaches at least cos(pi / 8) of it,
    # and never more than the amplitude (to rounding)
    assert 0.015 < np.ptp(dx) / 2 <= 0.020 + roundoff(scale=0.020, ops=4)
    model = _homed_model(RAIL="15 2")
    model.execute("HEAD")
    model.execute("SCAN 40")
    assert np.ptp([d for _, d in model.last_scan]) > 0.01


def _grey_at_marker(model: FilmScannerModel) -> np.ndarray:
    model.execute("HEAD")
    marker = min(model.film.markers[:4], key=lambda m: m.radius_mm)
    target = model.film.frame_top_mm(0) + marker.y_mm
    model.execute(f"FEED {round((target - model.carrier.film_um / 1000) / PIXEL_MM)}")
    grey = model.execute("GREY?")[0].split(" ")[2:]
    return np.array(grey, dtype=int)


def test_defocus_lowers_the_grey_peak_and_illum_darkens_edges() -> None:
    sharp = _grey_at_marker(_homed_model())
    blurred = _grey_at_marker(_homed_model(DEFOCUS="4000"))
    assert sharp.max() > 200
    assert blurred.max() < 0.8 * sharp.max()
    model = _homed_model(ILLUM="0.5")
    model.execute("FEED 64")                                 # leader -> clear band 0
    grey = np.array(model.execute("GREY?")[0].split(" ")[2:], dtype=int)
    assert grey[:16].mean() < 0.7 * grey[248:264].mean()


def test_filmnoise_adds_specks_to_the_background() -> None:
    def white_pixels(**faults: str) -> int:
        model = _homed_model(**faults)
        model.execute("HEAD")
        return sum(decode_bits(l.split()[2], PIXELS)[:40].sum() for l in model.execute("SCAN 20")[:-1])

    assert white_pixels() == 0
    assert white_pixels(FILMNOISE="0.2") > 5


# -- acceptance (§1.4, §5) --------------------------------------------------------------------------
def _scan_image(model: FilmScannerModel, lines: int) -> np.ndarray:
    reply = model.execute(f"SCAN {lines}")
    return np.array([decode_bits(l.split()[2], PIXELS) for l in reply[:-1]])


def test_marker_centres_recovered_without_faults() -> None:
    model = _homed_model()
    model.execute("HEAD")
    found = blob_centres(_scan_image(model, 300))
    ys = np.array([y for y, _ in model.last_scan])
    top = model.film.frame_top_mm(0)
    truth_cr = np.array([[m.col_px, np.interp(top + m.y_mm, ys, np.arange(ys.size))]
                         for m in model.film.markers if m.frame == 0])
    truth_cr = truth_cr[np.argsort(truth_cr[:, 0])]
    assert found.shape == truth_cr.shape
    rms = np.sqrt(np.mean((found - truth_cr) ** 2))
    assert rms <= 0.1, rms                                # §5: <= 0.1 px RMS without faults


def test_repeatability_of_repeated_scans_with_default_faults() -> None:
    """§1.4: repeated scans of one frame spread (peak to peak) 1 px across and 2 px along the feed,
    within a factor 1.5. 20 scans here (100 scans measured 0.86 / 2.57 px, see the report)."""
    model = FilmScannerModel(seed=4)
    for cmd in ("CLAMP BASE", "HOME", "CLAMP CARRIER"):
        model.execute(cmd)
    lines = 260
    centres = []
    for _ in range(20):
        model.execute("HEAD")
        centres.append(blob_centres(_scan_image(model, lines)))
        model.execute(f"FEED -{lines + 37 + 40}")            # back before the band: scan it again
    spread = np.ptp(np.array(centres), axis=0).mean(axis=0)
    assert 1 / 1.5 <= spread[0] <= 1.5, spread            # across the sensor, px
    assert 2 / 1.5 <= spread[1] <= 2 * 1.5, spread        # along the feed, px


def test_frame_time_is_modelled() -> None:
    model = _homed_model()
    model.execute("HEAD")
    assert model.execute("SCAN 344")[-1] == "OK 344 8605"   # 344 x (512/73 kHz + 18 ms) = 8.6 s
