"""Camera registration + multi-view fusion speed: planefuse's fused numba gather vs a naive baseline.

Scene: 4 cameras of ``default_camera_ring`` (360x288, no lens distortion so both methods use the same
plane homographies), 10 planes 0..1.8 m, 200x200 cells of 5 cm. Input per frame: one float32 foreground
likelihood image per camera. Output: fused per-plane log-odds (L, ny, nx).

* planefuse: ``CameraFusion.log_odds`` (quantise to 256 levels, one gather per camera and cell through
  the precomputed ``ImagePlaneLookup``, table look-up and sum in one numba kernel).
* baseline: ``cv2.warpPerspective`` (nearest neighbour) of every camera's likelihood onto every plane,
  then the same sensor model evaluated in numpy and summed over cameras.

Run: ``python benchmarks/bench_cameras.py`` (one core: OpenCV threads set to 1; numba is serial).
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from planefuse.geometry import CameraIntrinsics, H_image_plane_from_projection, PinholeCamera, default_camera_ring
from planefuse.grid import PlaneStack
from planefuse.vision import CameraFusion, FusionParams, lookups_from_cameras


def _baseline(fgs, H_grid_image, params: FusionParams, shape) -> np.ndarray:
    L, ny, nx = shape
    out = np.zeros(shape, dtype=np.float32)
    pd, pfa = params.p_detect, params.p_false_alarm
    for fg, Hs in zip(fgs, H_grid_image):
        for l in range(L):
            w = cv2.warpPerspective(fg, Hs[l], (nx, ny), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                                    borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
            r = np.log(w * pd + (1 - w) * (1 - pd)) - np.log(w * pfa + (1 - w) * (1 - pfa))
            out[l] += np.nan_to_num(r, nan=0.0)
    return out


def _time(fn, n: int) -> float:
    fn()
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n


def main() -> None:
    cv2.setNumThreads(1)
    rng = np.random.default_rng(0)
    cams = []
    for c in default_camera_ring():
        intr = CameraIntrinsics(c.K, c.intrinsics.width_px, c.intrinsics.height_px, np.zeros(5))
        cams.append(PinholeCamera(intr, c.T_world_cam, c.name))
    stack = PlaneStack.from_extent(np.linspace(0.0, 1.8, 10), (0, 10), (0, 10), 0.05)
    params = FusionParams()
    lookups = lookups_from_cameras(cams, stack, route="projection")
    fusion = CameraFusion(lookups, stack, params)
    G = np.linalg.inv(stack.H_grid_plane())  # grid (ix, iy) -> world XY
    H_grid_image = [
        [H_image_plane_from_projection(c.P_image_world, h) @ G for h in stack.heights_m] for c in cams
    ]
    # Foreground: smooth blobs in [0, 1] (quantised on 256 levels, as a subtractor's output is).
    fgs = []
    for c in cams:
        img = cv2.GaussianBlur(rng.random((c.intrinsics.height_px, c.intrinsics.width_px)).astype(np.float32),
                               (0, 0), 6)
        img = (img - img.min()) / (img.max() - img.min())
        fgs.append(np.round(img * 255).astype(np.float32) / 255)
    out = np.empty(stack.shape, dtype=np.float32)
    ours = fusion.log_odds(fgs, out=out).copy()
    base = _baseline(fgs, H_grid_image, params, stack.shape)
    agree = np.mean(np.abs(ours - base) < 1e-3)
    n = 200
    t_ours = _time(lambda: fusion.log_odds(fgs, out=out), n)
    t_base = _time(lambda: _baseline(fgs, H_grid_image, params, stack.shape), 20)
    t_warp = _time(lambda: [cv2.warpPerspective(fg, H, (stack.nx, stack.ny),
                                                flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP)
                            for fg, Hs in zip(fgs, H_grid_image) for H in Hs], 20)
    print(f"4 cameras 360x288 -> {stack.n_planes} planes x {stack.ny}x{stack.nx} cells, one core")
    print(f"{'method':<42}{'ms/frame':>10}{'frames/s':>10}")
    print(f"{'baseline: warpPerspective + numpy fusion':<42}{1e3 * t_base:>10.2f}{1 / t_base:>10.1f}")
    print(f"{'  of which the 40 warps alone':<42}{1e3 * t_warp:>10.2f}{1 / t_warp:>10.1f}")
    print(f"{'planefuse: fused numba gather + fusion':<42}{1e3 * t_ours:>10.2f}{1 / t_ours:>10.1f}")
    print(f"speed-up: {t_base / t_ours:.1f}x; cells agreeing within 1e-3: {agree:.4%}")


if __name__ == "__main__":
    main()
