"""Kernels of :class:`~planefuse.vision.GainCompensator`: the per-block median gain of a frame against its reference
and the frame divided by the gain field, each in one numba pass over the pixels (numpy's element-wise form made about
ten passes over the frame).

The rule is :class:`~planefuse.vision.GainCompensator`'s; tests/test_vision_illumination.py holds it in numpy and
compares the two bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["block_gain_medians", "divide_by_gain", "exact_median"]

#: Bins of the histogram that narrows a median down before the exact selection.
_MEDIAN_BINS = 1024


@njit(cache=True, error_model="numpy")
def exact_median(values, n, counts):  # pragma: no cover - numba
    """``np.median(values[:n])`` of float32 values, the same bits (the mean of the two middle values for even
    ``n``, in float32), in two passes: a histogram between the extremes finds the bins of the middle ranks (binning
    is monotone, so a bin holds a run of consecutive ranks), then only those bins' values are sorted.
    ``counts``: int64 scratch of ``_MEDIAN_BINS`` entries. ``n >= 1``."""
    lo = values[0]
    hi = values[0]
    for k in range(1, n):
        v = values[k]
        if v < lo:
            lo = v
        elif v > hi:
            hi = v
    if lo == hi:
        return lo
    nb = counts.size
    scale = nb / (np.float64(hi) - np.float64(lo))
    counts[:] = 0
    for k in range(n):
        b = int((np.float64(values[k]) - lo) * scale)
        counts[min(b, nb - 1)] += 1
    r1, r2 = (n - 1) // 2, n // 2  # the middle ranks (equal for odd n)
    below = 0  # values in the bins before b1
    b1 = 0
    while below + counts[b1] <= r1:
        below += counts[b1]
        b1 += 1
    b2, upto = b1, below + counts[b1]
    while upto <= r2:
        b2 += 1
        upto += counts[b2]
    middle = np.empty(upto - below, np.float32)
    m = 0
    for k in range(n):
        b = min(int((np.float64(values[k]) - lo) * scale), nb - 1)
        if b1 <= b <= b2:
            middle[m] = values[k]
            m += 1
    middle.sort()
    a, c = middle[r1 - below], middle[r2 - below]
    return np.float32(a + c) / np.float32(2.0)


@njit(cache=True, error_model="numpy")
def block_gain_medians(img, ref, valid, use_valid, dark, saturated, min_valid, ys, xs):  # pragma: no cover - numba
    """Per-block, per-channel median of ``img / max(ref, 1)`` over the pixels that tell the gain.

    Parameters
    ----------
    img : ndarray, shape (H, W, C), uint8
        The frame.
    ref : ndarray, shape (H, W, C), float32
        The reference background, in the first frame's units.
    valid : ndarray, shape (H, W), bool
        Background in the previous frame (read where ``use_valid``).
    use_valid : bool
    dark, saturated : float
        A pixel tells the gain where, in every channel, ``dark < ref < saturated`` and ``img < saturated``; with
        ``use_valid`` it must also be ``valid``, unless fewer than ``min_valid * H * W`` pixels are both (then the
        subtractor called nearly everything foreground: a cold model).
    min_valid : float
        That fraction; also the fewest telling pixels (share of its area) a block's own median needs, else it takes
        the whole image's median (1 where no pixel tells).
    ys, xs : ndarray of int64, shapes (rows + 1,), (cols + 1,)
        Block edges [px].

    Returns
    -------
    ndarray, shape (rows, cols, C), float32
    """
    h, w, n_ch = img.shape
    ok = np.empty((h, w), np.bool_)
    n_both = 0
    for y in range(h):
        for x in range(w):
            good = True
            for c in range(n_ch):
                r = ref[y, x, c]
                if not (r > dark and r < saturated and img[y, x, c] < saturated):
                    good = False
            ok[y, x] = good
            if good and valid[y, x]:
                n_both += 1
    if use_valid and n_both >= min_valid * (h * w):
        for y in range(h):
            for x in range(w):
                ok[y, x] = ok[y, x] and valid[y, x]
    rows, cols = len(ys) - 1, len(xs) - 1
    out = np.empty((rows, cols, n_ch), np.float32)
    buf = np.empty(h * w, np.float32)
    counts = np.empty(_MEDIAN_BINS, np.int64)
    glob = np.empty(0, np.float32)  # the whole image's medians, computed where a block needs them
    for i in range(rows):
        for j in range(cols):
            area = (ys[i + 1] - ys[i]) * (xs[j + 1] - xs[j])
            for c in range(n_ch):
                n = 0
                for y in range(ys[i], ys[i + 1]):
                    for x in range(xs[j], xs[j + 1]):
                        if ok[y, x]:
                            buf[n] = np.float32(img[y, x, c]) / max(ref[y, x, c], np.float32(1.0))
                            n += 1
                if n > 0 and n / area >= min_valid:
                    out[i, j, c] = exact_median(buf, n, counts)
                    continue
                if glob.size == 0:
                    glob = np.ones(n_ch, np.float32)
                    for cc in range(n_ch):
                        m = 0
                        for y in range(h):
                            for x in range(w):
                                if ok[y, x]:
                                    buf[m] = np.float32(img[y, x, cc]) / max(ref[y, x, cc], np.float32(1.0))
                                    m += 1
                        if m > 0:
                            glob[cc] = exact_median(buf, m, counts)
                out[i, j, c] = glob[c]
    return out


@njit(cache=True, error_model="numpy")
def divide_by_gain(img, field):  # pragma: no cover - numba
    """``clip(img / field, 0, 255)`` as uint8 (truncated), in float32: ``img`` (H, W, C) uint8, ``field`` (H, W, C)
    float32."""
    h, w, n_ch = img.shape
    out = np.empty((h, w, n_ch), np.uint8)
    for y in range(h):
        for x in range(w):
            for c in range(n_ch):
                v = np.float32(img[y, x, c]) / field[y, x, c]
                if v < 0:
                    v = np.float32(0.0)
                elif v > 255:
                    v = np.float32(255.0)
                out[y, x, c] = np.uint8(v)
    return out
