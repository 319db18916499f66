"""Throughput of marker detection (mirrorlab vs ``cv2.SimpleBlobDetector``) and of tracking.

Run: ``python benchmarks/bench_detection.py [--frames 100] [--repeat 3] [--track-frames 10000]``

Scenes (fixed seed, frames cycled from ``--frames`` distinct ones):

* **scanner**: 512 × 344 binary 0/255 frames (the film scanner's format) with 20 discs of radius
  3–8 px at sub-pixel centres;
* **camera**: 1920 × 1080 grey frames with 20 anti-aliased markers of radius 4–12 px, Gaussian blur
  σ = 1 px, noise σ = 2 grey levels, dark background at 30 and markers at 220.

On the same frames, interleaved (best of ``--repeat`` passes): mirrorlab ``subpixel`` with Otsu's
automatic threshold and with a fixed threshold, ``thesis`` (scanner frames), and
``cv2.SimpleBlobDetector`` with its default threshold sweep (50…220 step 10) and with a single
threshold (the fairest speed comparison). For each: frames/s, the ratio to SimpleBlobDetector and
the RMS centre error against the true centres (markers matched within 3 px; misses counted).
Goals: ≥ 2000 frames/s (scanner) and ≥ 200 frames/s (camera) for ``subpixel``.

Tracking: 50 markers on smooth random paths × ``--track-frames`` frames, detections shuffled in
every frame; time and frames/s for ``predictive`` and ``nearest``, and the fraction of frames in
which every track is right.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable

import cv2
import numpy as np
from mirrorlab.plugins.markers import detect_markers
from mirrorlab.plugins.tracking import track

SS = 8  # supersampling of the marker patches
SHIFT = 8


def _patch(radius: float, frac: np.ndarray) -> tuple[np.ndarray, int]:
    """Coverage patch (float, 0…1) of a disc whose centre is ``frac`` px from the patch's anchor pixel."""
    half = int(np.ceil(radius)) + 3
    n = 2 * half + 1
    canvas = np.zeros((n * SS, n * SS), np.uint8)
    cx, cy = (half + frac[0] + 0.5) * SS - 0.5, (half + frac[1] + 0.5) * SS - 0.5
    one = 1 << SHIFT
    cv2.ellipse(canvas, (int(round(cx * one)), int(round(cy * one))),
                (int(round(radius * SS * one)),) * 2, 0.0, 0.0, 360.0, 255, -1, cv2.LINE_AA, SHIFT)
    return cv2.resize(canvas.astype(np.float32) / 255.0, (n, n), interpolation=cv2.INTER_AREA), half


def _centres(rng: np.random.Generator, shape: tuple[int, int], n: int, rmax: float) -> np.ndarray:
    h, w = shape
    out: list[np.ndarray] = []
    while len(out) < n:
        p = rng.uniform(2 * rmax + 10, [w - 2 * rmax - 10, h - 2 * rmax - 10])
        if all(np.hypot(*(p - q)) > 4 * rmax + 8 for q in out):
            out.append(p)
    return np.array(out)


def camera_frame(rng: np.random.Generator, shape=(1080, 1920), n: int = 20) -> tuple[np.ndarray, np.ndarray]:
    centres = _centres(rng, shape, n, 12.0)
    cover = np.zeros(shape, np.float32)
    for c, r in zip(centres, rng.uniform(4.0, 12.0, n), strict=False):
        base = np.floor(c).astype(int)
        p, half = _patch(r, c - base)
        cover[base[1] - half:base[1] + half + 1, base[0] - half:base[0] + half + 1] += p
    img = 30.0 + 190.0 * cover
    img = cv2.GaussianBlur(img, (0, 0), 1.0) + rng.normal(0.0, 2.0, shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8), centres


def scanner_frame(rng: np.random.Generator, shape=(344, 512), n: int = 20) -> tuple[np.ndarray, np.ndarray]:
    centres = _centres(rng, shape, n, 8.0)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    out = np.zeros(shape, bool)
    for c, r in zip(centres, rng.uniform(3.0, 8.0, n), strict=False):
        out |= (xx - c[0]) ** 2 + (yy - c[1]) ** 2 <= r * r
    return out.astype(np.uint8) * np.uint8(255), centres


def blob_detector(single_threshold: bool) -> cv2.SimpleBlobDetector:
    p = cv2.SimpleBlobDetector_Params()
    p.blobColor = 255
    p.filterByArea, p.minArea, p.maxArea = True, 5.0, 1e5
    p.filterByCircularity = p.filterByInertia = p.filterByConvexity = False
    p.minDistBetweenBlobs = 5.0
    if single_threshold:
        p.minThreshold, p.maxThreshold, p.thresholdStep, p.minRepeatability = 120.0, 121.0, 10.0, 1
    return cv2.SimpleBlobDetector_create(p)


def _timed(fns: dict[str, Callable[[np.ndarray], np.ndarray]], frames: list[np.ndarray], repeat: int):
    best = dict.fromkeys(fns, np.inf)
    results: dict[str, list[np.ndarray]] = {}
    for _ in range(repeat):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            out = [fn(f) for f in frames]
            best[name] = min(best[name], time.perf_counter() - t0)
            results[name] = out
    return best, results


def _accuracy(found: list[np.ndarray], truth: list[np.ndarray]) -> tuple[float, int]:
    err, missed = [], 0
    for xy, t in zip(found, truth, strict=False):
        if len(xy) == 0:
            missed += len(t)
            continue
        d = np.linalg.norm(xy[None, :, :] - t[:, None, :], axis=2)
        j = d.argmin(axis=1)
        ok = d[np.arange(len(t)), j] < 3.0
        missed += int((~ok).sum())
        err.append(xy[j[ok]] - t[ok])
    e = np.concatenate(err) if err else np.zeros((0, 2))
    return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1)))) if len(e) else float("nan"), missed


def bench_detection(kind: str, n_frames: int, repeat: int, goal: float) -> None:
    rng = np.random.default_rng(1)
    make = scanner_frame if kind == "scanner" else camera_frame
    scenes = [make(rng) for _ in range(n_frames)]
    frames, truth = [s[0] for s in scenes], [s[1] for s in scenes]
    sbd, sbd1 = blob_detector(False), blob_detector(True)

    def keypoints(det):
        return lambda f: np.array([k.pt for k in det.detect(f)], float).reshape(-1, 2)

    fns = {
        "mirrorlab subpixel (Otsu)": lambda f: detect_markers(f).xy,
        "mirrorlab subpixel (T=120)": lambda f: detect_markers(f, threshold=120).xy,
    }
    if kind == "scanner":
        fns["mirrorlab thesis (Otsu)"] = lambda f: detect_markers(f, method="thesis").xy
    fns["SimpleBlobDetector (default sweep)"] = keypoints(sbd)
    fns["SimpleBlobDetector (one threshold)"] = keypoints(sbd1)
    best, results = _timed(fns, frames, repeat)
    ref = best["SimpleBlobDetector (one threshold)"]
    h, w = frames[0].shape
    print(f"\n{kind}: {w}x{h} {'binary' if kind == 'scanner' else 'grey'} frames, 20 markers, "
          f"{n_frames} frames, best of {repeat}")
    for name, t in best.items():
        rms, missed = _accuracy(results[name], truth)
        print(f"  {name:36s} {n_frames / t:9.0f} frames/s  x{ref / t:5.2f} vs SBD(one)  "
              f"x{best['SimpleBlobDetector (default sweep)'] / t:6.2f} vs SBD(sweep)  "
              f"RMS {rms:.4f} px  missed {missed}")
    fps = n_frames / min(best["mirrorlab subpixel (Otsu)"], best["mirrorlab subpixel (T=120)"])
    fps_auto = n_frames / best["mirrorlab subpixel (Otsu)"]
    print(f"  goal >= {goal:.0f} frames/s: fixed threshold {fps:.0f} ({'met' if fps >= goal else 'NOT met'}), "
          f"Otsu {fps_auto:.0f} ({'met' if fps_auto >= goal else 'NOT met'})")


def bench_tracking(n_frames: int, n_markers: int = 50) -> None:
    rng = np.random.default_rng(2)
    t = np.arange(n_frames)[:, None]
    grid = np.stack(np.meshgrid(np.arange(10), np.arange(5)), -1).reshape(-1, 2)[:n_markers]
    c = 80.0 + 150.0 * grid
    r, om, ph = rng.uniform(10, 40, n_markers), rng.uniform(0.01, 0.1, n_markers), rng.uniform(0, 6.3, n_markers)
    truth = np.stack([c[:, 0] + r * np.cos(om * t + ph), c[:, 1] + r * np.sin(om * t + ph)], -1)
    frames = [xy[rng.permutation(n_markers)] + rng.normal(0, 0.1, (n_markers, 2)) for xy in truth]
    order = np.lexsort((truth[0, :, 0], truth[0, :, 1]))
    print(f"\ntracking: {n_markers} markers x {n_frames} frames (0.1 px noise, shuffled detections)")
    for method in ("predictive", "nearest"):
        t0 = time.perf_counter()
        out = track(frames, method, gate=10.0)
        dt = time.perf_counter() - t0
        ok = out.n_tracks == n_markers and bool(np.all(np.abs(out.xy - truth[:, order]) < 1.0))
        print(f"  {method:10s} {dt:7.2f} s  {n_frames / dt:8.0f} frames/s  tracks {out.n_tracks}  "
              f"all tracks right: {ok}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100, help="distinct frames per scene")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--track-frames", type=int, default=10_000)
    args = ap.parse_args(argv)
    print(f"OpenCV {cv2.__version__} ({cv2.getNumThreads()} threads), NumPy {np.__version__}")
    bench_detection("scanner", args.frames, args.repeat, 2000.0)
    bench_detection("camera", args.frames, args.repeat, 200.0)
    bench_tracking(args.track_frames)
    return 0


if __name__ == "__main__":
    sys.exit(main())
