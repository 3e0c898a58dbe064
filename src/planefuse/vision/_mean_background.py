"""A per-pixel running-average background model in one numba pass (``ForegroundParams.method = "mean"``).

Each pixel keeps one background colour ``mu`` (float32 per channel), the running average of its frames. A frame's
pixel ``x`` is background when its squared colour distance to ``mu`` is within the threshold (the decision OpenCV's
KNN makes against each of its samples, here against their mean), else a shadow when it is a darker copy of the
background (OpenCV's MOG2 / KNN shadow rule, Prati et al. 2003: ``x ~ a mu`` with ``tau <= a <= 1`` and
``|x - a mu|^2 < threshold a^2``), else foreground. Background pixels are learnt at the
learning rate, foreground and shadow pixels at a fraction of it (``foreground_rate``): a person who stands still
is not absorbed within the history, while a background object that moved (a ghost) still heals, more slowly. The
mask uses OpenCV's values (0, 127 shadow, 255 foreground), so the cleaning, likelihood and relearning of
:class:`~planefuse.vision.BackgroundSubtractor` are the same as for OpenCV's subtractors.

One mean per pixel cannot hold a background that alternates between colours (leaves in the wind, a flickering
screen), which KNN's samples can; the running average follows illumination changes only at its rate (1/history per
frame): on the simulator (noise and a slow global drift) it is at or above KNN, on real video (EPFL terrace) it
calls a large part of the image foreground after a camera's exposure changes (docs/results.md).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: OpenCV's shadow threshold ``tau`` (MOG2 and KNN): a shadow keeps at least half the background's brightness.
SHADOW_TAU = 0.5


class MeanBackground:
    """Running-average background model with OpenCV's ``apply(frame, learningRate)`` interface.

    Parameters
    ----------
    threshold : float
        Squared colour distance above which a pixel is not background [grey levels squared, summed over
        channels].
    history : int
        Frames of the automatic learning rate's horizon: the rate is ``1 / min(frames seen, history)``.
    detect_shadows : bool
        Mark darker copies of the background as shadow (127) instead of foreground (255).
    foreground_rate : float
        Rate at which foreground and shadow pixels are learnt, relative to the learning rate, in [0, 1] (0: never,
        a conservative update; 1: every pixel alike, a blind update).
    """

    def __init__(self, threshold: float, history: int, detect_shadows: bool, foreground_rate: float) -> None:
        self.threshold = float(threshold)
        self.history = int(history)
        self.detect_shadows = bool(detect_shadows)
        self.foreground_rate = float(foreground_rate)
        self._mean: np.ndarray | None = None
        self._n_seen = 0

    def apply(self, frame: np.ndarray, learningRate: float = -1.0,  # noqa: N803 - OpenCV's name
              foreground_rate: float | None = None) -> np.ndarray:
        """Classify ``frame`` (H, W) or (H, W, 3) uint8 against the background, then learn it.

        ``learningRate`` in [0, 1] is the running average's rate for this frame (1 restarts the model from the
        frame); negative is automatic, ``1 / min(frames seen, history)``. ``foreground_rate`` replaces the
        model's own for this frame (1 while a changed scene is relearnt). Returns the (H, W) uint8 mask: 0
        background, 127 shadow, 255 foreground (all 255 on the first frame, when nothing is known yet).
        """
        fg = self.foreground_rate if foreground_rate is None else float(foreground_rate)
        self._n_seen += 1
        rate = 1.0 / min(self._n_seen, self.history) if learningRate < 0 else float(learningRate)
        if self._mean is None or self._mean.shape != frame.shape or rate >= 1.0:
            self._mean = frame.astype(np.float32)
            return np.full(frame.shape[:2], 255, np.uint8)
        mask = np.empty(frame.shape[:2], np.uint8)
        kernel = _learn_grey if frame.ndim == 2 else _learn_bgr
        kernel(np.ascontiguousarray(frame), self._mean, np.float32(self.threshold), self.detect_shadows,
               np.float32(SHADOW_TAU), np.float32(rate), np.float32(rate * fg), mask)
        return mask

    def getDist2Threshold(self) -> float:  # noqa: N802 - OpenCV KNN's name for the same quantity
        """The squared colour distance threshold [grey levels squared]."""
        return self.threshold

    def background(self) -> np.ndarray | None:
        """The background colours (H, W[, 3]) float32 learnt so far (None before the first frame)."""
        return None if self._mean is None else self._mean.copy()


# The kernels: one pass over the pixels, the mask against ``mean``, then ``mean += q (x - mean)`` with ``q = rate``
# on background pixels and ``fg_rate`` on the others. Written over the flat pixel index, channels spelt out and
# without branches (every pixel computes the shadow test; error_model "numpy": 0 / 0 is NaN, which fails every
# comparison, as the test of mm > 0 also says), so that LLVM vectorises the loop: 0.07 ms per 360x288 BGR frame
# against 0.20 for the same equations with branches and 0.43 with a loop over the channels, the same bits.

@njit(cache=True, error_model="numpy")
def _learn_bgr(img, mean, threshold, shadows, tau, rate, fg_rate, mask):  # pragma: no cover - numba
    n = mask.size
    x, m, out = img.reshape(3 * n), mean.reshape(3 * n), mask.reshape(n)
    for i in range(n):
        j = 3 * i
        x0, x1, x2 = np.float32(x[j]), np.float32(x[j + 1]), np.float32(x[j + 2])
        m0, m1, m2 = m[j], m[j + 1], m[j + 2]
        d0, d1, d2 = x0 - m0, x1 - m1, x2 - m2
        fg = d0 * d0 + d1 * d1 + d2 * d2 > threshold
        # x ~ a mu with tau <= a <= 1: a darker copy of the background, a shadow (OpenCV's rule)
        mm = m0 * m0 + m1 * m1 + m2 * m2
        a = (x0 * m0 + x1 * m1 + x2 * m2) / mm
        e0, e1, e2 = x0 - a * m0, x1 - a * m1, x2 - a * m2
        shadow = shadows and fg and mm > 0 and tau <= a and a <= 1 and e0 * e0 + e1 * e1 + e2 * e2 < threshold * a * a
        out[i] = 127 if shadow else (255 if fg else 0)
        q = fg_rate if fg else rate
        m[j] = m0 + q * d0
        m[j + 1] = m1 + q * d1
        m[j + 2] = m2 + q * d2


@njit(cache=True, error_model="numpy")
def _learn_grey(img, mean, threshold, shadows, tau, rate, fg_rate, mask):  # pragma: no cover - numba
    n = mask.size
    x, m, out = img.reshape(n), mean.reshape(n), mask.reshape(n)
    for i in range(n):
        xi, mi = np.float32(x[i]), m[i]
        d = xi - mi
        fg = d * d > threshold
        # grey: x = a m exactly, so a shadow is any darkening to no less than tau m
        shadow = shadows and fg and mi > 0 and tau * mi <= xi and xi <= mi
        out[i] = 127 if shadow else (255 if fg else 0)
        m[i] = mi + (fg_rate if fg else rate) * d
