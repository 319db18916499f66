"""Throughput of mirror triangulation: mirrorlab midpoint vs ``cv2.triangulatePoints``.

Run: ``python benchmarks/bench_triangulation.py [--points 1000000] [--repeat 3]``

One synthetic camera + plane mirror (the spec §10 geometry), N markers with 0.3 px image noise in
both the direct and the mirror image. Both methods start from the same pixel coordinates:

* mirrorlab: pixels → world rays (one 3×3 product) → :func:`triangulate_mirror` (eqs 3.5–3.7, with
  all its checks: parallel rays, behind-camera, miss distance, intersection angle);
* OpenCV: ``cv2.triangulatePoints(P, P·H, x1, x2)`` (H = 4×4 reflection) → dehomogenise.

Prints the best-of-``repeat`` wall time of each (runs interleaved), the throughput ratio (goal ≥ 10×), both 3-D RMS
errors and the peak resident memory. Keeps well under 4 GB and 60 s for 1e6 points.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time

import cv2
import numpy as np
from mirrorlab.plugins.photogrammetry import reflect, reflection_matrix, triangulate_mirror

F1 = np.array([435.68, 202.6, 1442.024])
G = np.array([-291.62, -52.76, 487.56])
NORMAL = np.array([np.cos(np.deg2rad(50.0)), 0.0, np.sin(np.deg2rad(50.0))])


def _scene(n: int, sigma: float, seed: int = 0):
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-100, -100, 150], [300, 200, 450], size=(2 * n, 3))
    pts = pts[(pts - G) @ NORMAL > 30.0][:n]
    target = 0.5 * (pts.mean(0) + reflect(pts.mean(0), G, NORMAL))
    z = (target - F1) / np.linalg.norm(target - F1)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z])
    K = np.array([[1500.0, 0, 640], [0, 1500.0, 480], [0, 0, 1]])
    P = K @ np.c_[R, -R @ F1]

    def project(X):
        h = X @ P[:, :3].T + P[:, 3]
        return h[:, :2] / h[:, 2:]

    xy1 = project(pts) + rng.normal(0, sigma, (len(pts), 2))
    xy2 = project(reflect(pts, G, NORMAL)) + rng.normal(0, sigma, (len(pts), 2))
    return pts, K, R, P, xy1, xy2


def _best_interleaved(fns, repeat: int):
    """Best wall time of each function, run alternately (fair on a busy machine)."""
    best, out = [np.inf] * len(fns), [None] * len(fns)
    for _ in range(repeat):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            out[i] = fn()
            best[i] = min(best[i], time.perf_counter() - t0)
    return best, out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)

    pts, K, R, P, xy1, xy2 = _scene(args.points, 0.3)
    n = len(pts)
    ray_matrix = np.linalg.inv(K).T @ R  # row-vector pixels -> world ray directions

    def pixels_to_rays(xy):
        # world ray = R^T K^-1 [x, y, 1], coordinate-wise (OpenBLAS threading on an (N,2)@(2,3)
        # product is erratic on a busy 2-core machine)
        u = np.empty((len(xy), 3))
        x, y = xy[:, 0].copy(), xy[:, 1].copy()
        for i in range(3):
            u[:, i] = x * ray_matrix[0, i] + y * ray_matrix[1, i] + ray_matrix[2, i]
        return u

    def mirrorlab_midpoint():
        return triangulate_mirror(F1, G, NORMAL, pixels_to_rays(xy1), pixels_to_rays(xy2)).points

    P2 = P @ reflection_matrix(G, NORMAL)
    x1t, x2t = np.ascontiguousarray(xy1.T), np.ascontiguousarray(xy2.T)

    def opencv():
        Xh = cv2.triangulatePoints(P, P2, x1t, x2t)
        return (Xh[:3] / Xh[3]).T

    u1, u2p = pixels_to_rays(xy1), pixels_to_rays(xy2)

    def midpoint_from_rays():
        return triangulate_mirror(F1, G, NORMAL, u1, u2p).points

    (t_mid, t_rays, t_cv), (X_mid, _, X_cv) = _best_interleaved(
        [mirrorlab_midpoint, midpoint_from_rays, opencv], args.repeat)

    def rms(X):
        return float(np.sqrt(np.mean(np.sum((X - pts) ** 2, axis=1))))

    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f"points: {n:,}  (0.3 px noise, best of {args.repeat}; OpenCV {cv2.__version__}, NumPy {np.__version__})")
    print(f"mirrorlab midpoint     : {t_mid:8.3f} s  {n / t_mid / 1e6:8.2f} Mpts/s  3-D RMS {rms(X_mid):.4f} mm"
          "  (pixels -> rays -> points)")
    print(f"  rays given (triang.) : {t_rays:8.3f} s  {n / t_rays / 1e6:8.2f} Mpts/s  (rays given: "
          f"{t_cv / t_rays:.1f}x OpenCV)")
    print(f"cv2.triangulatePoints  : {t_cv:8.3f} s  {n / t_cv / 1e6:8.2f} Mpts/s  3-D RMS {rms(X_cv):.4f} mm")
    ratio = t_cv / t_mid
    print(f"throughput ratio midpoint / OpenCV: {ratio:.1f}x  (goal >= 10x: {'met' if ratio >= 10 else 'NOT met'})")
    print(f"peak resident memory: {peak_mb:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
