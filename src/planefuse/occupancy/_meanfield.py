"""Generative multi-view occupancy: mean-field posterior marginals of ground locations (Fleuret et al. 2008, §V, App. A).

Model (per instant; K ground locations, C cameras; see docs/cameras.md, "Generative sensor model")::

    X_k in {0, 1}                  a person stands at location k; prior P(X_k = 1) = eps, independent
    R_ck                           silhouette of that person in camera c: an axis-aligned pixel box (or nothing)
    A_c(X) = union_{k: X_k=1} R_ck                                           synthetic foreground image
    B_c    in [0, 1]^pixels        observed foreground (background subtraction)
    W_c    in {0, 1}^pixels        observed pixels (0 = ignored region: no evidence)
    Psi(B, A) = |W (B (1 - A) + (1 - B) A)| / |W A|                        pseudo-distance, |.| = sum over pixels
    P(B | X) prop. to prod_c exp(-Psi(B_c, A_c(X)) / sigma)

Mean-field approximation ``P(X | B) ~ prod_k q_k^X_k (1 - q_k)^(1 - X_k)``, with the paper's closed form: the
expected pseudo-distance is replaced by the pseudo-distance of the expected (average) synthetic image::

    Abar_c = 1 - prod_k (1 - q_k R_ck)                                      P(pixel covered) under q
    Abar_c^{k,1} = Abar_c on pixels outside R_ck, 1 inside
    Abar_c^{k,0} = Abar_c outside R_ck, 1 - (1 - Abar_c) / (1 - q_k) inside    (location k removed)
    q_k <- 1 / (1 + exp(log((1 - eps) / eps) + sum_c [Psi(B_c, Abar_c^{k,1}) - Psi(B_c, Abar_c^{k,0})] / sigma))

iterated to a fixed point from ``q = eps``, with damping ``q <- damping q_old + (1 - damping) q_new``, until no
marginal moves by more than ``tolerance * max(q_k, eps)`` (relative: on fine grids every q_k is small).

Every sum over a silhouette is four look-ups in an integral image. ``Abar`` itself is built without a loop over
the pixels of each box: each box multiplies its four corners of a 2-D "difference" array by ``(1 - q_k)`` or
``1 / (1 - q_k)``, and a running 2-D product turns it into ``prod_k (1 - q_k R_ck)`` for every pixel in one pass
(the multiplicative analogue of a summed-area table). One iteration therefore costs O(pixels + K C), in a
single numba kernel with no Python loop over locations or iterations; its cameras can run on numba's threads
(``threads``), each writing its own row of terms, summed in camera order: the same bits on any number of
threads. The damping 0.8 is POM's: its first iterate from the prior is ``0.8 eps + 0.2 target`` (measured on
its program, docs/results.md). Three exact-or-bounded economies:

* the pass covers only the bounding region of the boxes in the synthetic image (``Abar = 0`` outside it, where
  the integral images are its edge values: look-ups are clamped into it); every box's four corner positions in
  that region's integral image are recomputed only on the iterations where the region changes (on fine grids it
  stays the whole covered area while every location rises from the prior);
* marginals below ``1e-3 eps`` (and below ``ignored_below``) are left out of ``Abar``;
* a location whose last target marginal was below 1e-8 is *dormant*: damped towards 0 without evaluation,
  evaluated again every 5th iteration and before convergence is declared (its marginal differs from the full
  update's by less than about 1e-8).

Bookkeeping that changes no bit of the marginals (``tests/test_occupancy.py`` checks them against a plain
pixel-by-pixel iteration and, in the benchmark's check, against the previous kernel): the update keeps the lists,
in increasing k, of the locations in the synthetic image and of those to evaluate, and the cameras' loops visit
only these; a camera's region is rescanned only on iterations after the set of locations in the synthetic image
changed; W is not read where every pixel is observed; a binary foreground is handed to the kernel as float32 (the
same values, half the bytes); box corners are int32. The kernel is bound by memory traffic more than by
arithmetic (about 20 MB of arrays per iteration at 200 x 200 locations and 4 cameras of 360 x 288).

A box covering no observed pixel, or an image whose synthetic image is empty, is guarded by ``|W A| >= 1`` pixel
(the pseudo-distance of an empty synthetic image is otherwise undefined).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import numba
from numba import njit, prange

__all__ = ["GenerativeParams", "MeanFieldResult", "MeanFieldSolver", "Silhouettes", "occupancy_marginals"]

#: Largest marginal the solver holds (1 - q_k divides the synthetic image; see module notes).
Q_MAX = 1.0 - 1e-6
#: Marginals below this fraction of the prior are left out of the average synthetic image (each would change it
#: by less than 1e-3 of what the prior's expected covering does).
Q_NEGLIGIBLE = 1e-3
#: A location whose log-odds of absence exceed this (target marginal < 1e-8) is dormant: only damped towards 0,
#: evaluated again on every REFRESH-th iteration and on the iteration that confirms convergence.
E_DORMANT = 18.42  # log(1e8)
REFRESH = 5


@dataclass(frozen=True)
class GenerativeParams:
    """Parameters of the generative model and of its mean-field solver.

    Attributes
    ----------
    prior : float
        Prior probability eps that a person stands at a location (POM ``PRIOR``, default 0.01).
    sigma : float
        Scale of the pseudo-distance: ``P(B|X) ~ exp(-Psi / sigma)`` (POM ``SIGMA_IMAGE_DENSITY``, default 0.01).
    max_iterations : int
        Bound on the fixed-point iterations (POM ``MAX_NB_SOLVER_ITERATIONS``, default 100).
    damping : float
        Weight in [0, 1) of the previous iterate in each update. The plain fixed point (0) oscillates: every
        location explains the same foreground at once. 0.8 is POM's (its first iterate from the prior is
        ``0.8 eps + 0.2 target``, measured on its program) and was also the best of 0-0.9 on POM's test frames
        160-174 (agreement with POM's marginals, docs/results.md; reported on 175-189).
    tolerance : float
        Stop when no marginal moved by more than this in one iteration.
    ignored_below : float
        Locations whose marginal is below this are left out of the average synthetic image (POM
        ``PROBA_IGNORED`` p: ``ignored_below = 1 - p``; 0 = none left out). They are still updated.
    """

    prior: float = 0.01
    sigma: float = 0.01
    max_iterations: int = 100
    damping: float = 0.8
    tolerance: float = 1e-3
    ignored_below: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 < self.prior < 1.0:
            raise ValueError(f"GenerativeParams.prior must be in (0, 1), got {self.prior}")
        if not self.sigma > 0.0:
            raise ValueError(f"GenerativeParams.sigma must be > 0, got {self.sigma}")
        if int(self.max_iterations) < 1:
            raise ValueError(f"GenerativeParams.max_iterations must be >= 1, got {self.max_iterations}")
        if not 0.0 <= self.damping < 1.0:
            raise ValueError(f"GenerativeParams.damping must be in [0, 1), got {self.damping}")
        if not self.tolerance >= 0.0:
            raise ValueError(f"GenerativeParams.tolerance must be >= 0, got {self.tolerance}")
        if not 0.0 <= self.ignored_below < 1.0:
            raise ValueError(f"GenerativeParams.ignored_below must be in [0, 1), got {self.ignored_below}")


@dataclass(frozen=True)
class Silhouettes:
    """One silhouette box per camera and ground location.

    Attributes
    ----------
    boxes_px : ndarray, shape (C, K, 4), int32
        ``(x_min, y_min, x_max, y_max)`` pixels, inclusive, top-left origin, inside the image; all -1 where the
        location is not visible in the camera.
    image_sizes : tuple of (height_px, width_px)
        Size of each camera's image.
    """

    boxes_px: np.ndarray
    image_sizes: tuple[tuple[int, int], ...]

    def __post_init__(self) -> None:
        b = np.asarray(self.boxes_px)
        if b.ndim != 3 or b.shape[2] != 4:
            raise ValueError(f"boxes_px must have shape (C, K, 4), got {b.shape}")
        sizes = tuple((int(h), int(w)) for h, w in self.image_sizes)
        if len(sizes) != b.shape[0]:
            raise ValueError(f"image_sizes has {len(sizes)} entries for {b.shape[0]} cameras")
        b = b.astype(np.int32)
        vis = b[..., 0] >= 0
        for c, (h, w) in enumerate(sizes):
            if h <= 0 or w <= 0:
                raise ValueError(f"camera {c}: image size must be positive, got {h}x{w}")
            bc = b[c][vis[c]]
            bad = (bc[:, 0] > bc[:, 2]) | (bc[:, 1] > bc[:, 3]) | (bc[:, 2] >= w) | (bc[:, 3] >= h) | (bc[:, 1] < 0)
            if bad.any():
                k = int(np.nonzero(vis[c])[0][np.argmax(bad)])
                raise ValueError(f"camera {c}, location {k}: box {b[c, k].tolist()} is empty or outside the "
                                 f"{w}x{h} image")
        b[~vis] = -1
        b.setflags(write=False)
        object.__setattr__(self, "boxes_px", b)
        object.__setattr__(self, "image_sizes", sizes)

    @property
    def n_cameras(self) -> int:
        """Number of cameras C."""
        return self.boxes_px.shape[0]

    @property
    def n_locations(self) -> int:
        """Number of ground locations K."""
        return self.boxes_px.shape[1]

    @property
    def visible(self) -> np.ndarray:
        """(C, K) bool: the location has a silhouette in the camera."""
        return self.boxes_px[..., 0] >= 0


@dataclass(frozen=True)
class MeanFieldResult:
    """Output of :func:`occupancy_marginals`.

    Attributes
    ----------
    marginals : ndarray, shape (K,), float64
        Posterior marginal ``q_k = P(X_k = 1 | B)`` under the mean-field approximation.
    n_iterations : int
        Fixed-point iterations run.
    converged : bool
        The last iteration moved no marginal by more than the tolerance.
    """

    marginals: np.ndarray
    n_iterations: int
    converged: bool


def _check_images(images: Sequence[np.ndarray], sizes, what: str, binary: bool) -> list[np.ndarray]:
    if len(images) != len(sizes):
        raise ValueError(f"{what}: expected {len(sizes)} images (one per camera), got {len(images)}")
    out = []
    for c, (img, (h, w)) in enumerate(zip(images, sizes)):
        a = np.asarray(img)
        if a.shape != (h, w):
            raise ValueError(f"{what}[{c}]: expected shape ({h}, {w}) (rows x cols), got {a.shape}")
        if binary:
            out.append(a.astype(bool).astype(np.float64))
        elif a.dtype == np.uint8:
            out.append(a.astype(np.float64) / 255.0)
        elif a.dtype == bool:
            out.append(a.astype(np.float64))
        else:
            a = np.asarray(a, dtype=np.float64)
            if not np.isfinite(a).all() or a.min() < 0.0 or a.max() > 1.0:
                raise ValueError(f"{what}[{c}]: float foreground must be finite and in [0, 1]")
            out.append(a)
    return out


class MeanFieldSolver:
    """The mean-field fixed point for one set of silhouettes, with its work buffers allocated once.

    Parameters
    ----------
    silhouettes : Silhouettes
    params : GenerativeParams
    threads : int
        Threads for the cameras' terms (numba's pool, at most ``numba.config.NUMBA_NUM_THREADS``). 1 (default)
        runs the serial kernel; more runs the cameras in parallel, with bit-identical marginals. It pays only
        where a camera's work per iteration is large (many locations, large images) and cores are free.
    """

    def __init__(self, silhouettes: Silhouettes, params: GenerativeParams = GenerativeParams(),
                 threads: int = 1) -> None:
        if int(threads) != threads or threads < 1:
            raise ValueError(f"threads must be an integer >= 1, got {threads}")
        self.silhouettes = silhouettes
        self.params = params
        self.threads = int(threads)
        sizes = silhouettes.image_sizes
        self._n_px = np.array([h * w for h, w in sizes], dtype=np.int64)
        self._n_ii = np.array([(h + 1) * (w + 1) for h, w in sizes], dtype=np.int64)
        self._px_off = np.concatenate([[0], np.cumsum(self._n_px)]).astype(np.int64)
        self._ii_off = np.concatenate([[0], np.cumsum(self._n_ii)]).astype(np.int64)
        self._hw = np.array(sizes, dtype=np.int64).reshape(-1, 2)
        n_ii = int(self._ii_off[-1])
        self._D = np.zeros(n_ii, dtype=np.float64)        # difference array (and the constant integral images)
        self._I2 = np.zeros(2 * n_ii, dtype=np.float64)   # interleaved integral images of W Abar, W B Abar
        self._ones = np.ones(int(self._px_off[-1]))          # W where every pixel is observed

    def solve(self, foregrounds: Sequence[np.ndarray], observed: Sequence[np.ndarray | None] | None = None,
              initial=None, prior=None) -> MeanFieldResult:
        """Posterior marginals of every location given one instant's foreground images.

        Parameters
        ----------
        foregrounds : sequence of C arrays (height_px, width_px)
            Foreground per camera: bool, uint8 (0..255, scaled to [0, 1]) or float in [0, 1].
        observed : sequence of C (bool arrays (height_px, width_px) or None), optional
            False on ignored pixels (unobserved regions: no evidence either way); None = all observed.
        initial : array_like, shape (K,), optional
            Starting marginals (default: the prior).
        prior : array_like, shape (K,), optional
            Prior of each location, in (0, 1) (default: ``params.prior`` everywhere): what is known of the
            locations before this instant's images, e.g. people tracked up to it. ``params.prior`` still sets the
            scale of the convergence test and of the locations left out of the synthetic image.

        Returns
        -------
        MeanFieldResult
        """
        sil, p = self.silhouettes, self.params
        sizes = sil.image_sizes
        fg = _check_images(foregrounds, sizes, "foregrounds", binary=False)
        if observed is not None and len(observed) != len(sizes):
            raise ValueError(f"observed: expected {len(sizes)} masks (None for all observed), got {len(observed)}")
        weighted = observed is not None and any(o is not None for o in observed)
        if weighted:
            w_img = _check_images([np.ones(s, bool) if o is None else o for o, s in zip(observed, sizes)], sizes,
                                  "observed", binary=True)
            W = np.concatenate([w.ravel() for w in w_img])
        else:
            W = self._ones  # all observed: the kernel does not read W (weighted False)
        B = np.concatenate([f.ravel() for f in fg])
        B32 = B.astype(np.float32)
        if np.array_equal(B32, B):
            B = B32  # binary (or otherwise float32-exact) foreground: half the bytes for the kernel to read, same values
        K = sil.n_locations
        if prior is None:
            log_prior_ratio = np.full(K, np.log((1.0 - p.prior) / p.prior))
        else:
            prior = np.asarray(prior, dtype=np.float64).ravel()
            if prior.shape != (K,) or not np.all((prior > 0.0) & (prior < 1.0)):
                raise ValueError(f"prior must hold {K} location priors in (0, 1), got shape {prior.shape}")
            log_prior_ratio = np.log1p(-prior) - np.log(prior)
        if initial is None:
            q = np.full(K, p.prior, dtype=np.float64) if prior is None else prior.copy()
        else:
            q = np.array(initial, dtype=np.float64).ravel()
            if q.shape != (K,) or not np.isfinite(q).all():
                raise ValueError(f"initial must hold {K} finite marginals, got shape {q.shape}")
        q = np.clip(q, 0.0, Q_MAX)
        args = (B, W, weighted, self._hw, self._px_off, self._ii_off, sil.boxes_px, q, self._D, self._I2,
                log_prior_ratio, 1.0 / p.sigma, int(p.max_iterations), float(p.damping),
                float(p.tolerance), float(p.ignored_below), Q_MAX, float(p.prior))
        if self.threads == 1:
            n_iter, converged = _solve(*args)
        else:
            before = numba.get_num_threads()
            numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
            try:
                n_iter, converged = _solve_parallel(*args)
            finally:
                numba.set_num_threads(before)
        return MeanFieldResult(q, int(n_iter), bool(converged))


def occupancy_marginals(foregrounds: Sequence[np.ndarray], silhouettes: Silhouettes,
                        params: GenerativeParams = GenerativeParams(),
                        observed: Sequence[np.ndarray | None] | None = None) -> MeanFieldResult:
    """One-call form of :class:`MeanFieldSolver` (allocates its buffers each call)."""
    return MeanFieldSolver(silhouettes, params).solve(foregrounds, observed)


@njit(cache=True, boundscheck=False)
def _box_sum(I, o, w1, x0, y0, x1, y1):  # pragma: no cover - compiled
    # sum over the inclusive box of the image whose integral image (h+1, w+1) starts at I[o]
    return I[o + (y1 + 1) * w1 + x1 + 1] - I[o + y0 * w1 + x1 + 1] - I[o + (y1 + 1) * w1 + x0] + I[o + y0 * w1 + x0]


@njit(cache=True, boundscheck=False)
def _integral(img, W, h, w, po, I, o):  # pragma: no cover - compiled
    # I = integral image (h+1, w+1) of W * img
    w1 = w + 1
    for x in range(w1):
        I[o + x] = 0.0
    for y in range(h):
        I[o + (y + 1) * w1] = 0.0
        run = 0.0
        for x in range(w):
            run += W[po + y * w + x] * img[po + y * w + x]
            I[o + (y + 1) * w1 + x + 1] = I[o + y * w1 + x + 1] + run


@njit(cache=True, boundscheck=False, fastmath=False)
def _abar_pass(D, W, B, I2, prev, o, wl, hl, p0, w, weighted):  # pragma: no cover - compiled
    # Running 2-D product of the difference array D (local (hl + 1) x (wl + 1) at D[o]) -> Abar = 1 - product, and
    # the interleaved integral images of W Abar and W B Abar (I2 at 2 o). Rows go four at a time: each row's
    # running product and sums are serial along x, and four independent chains keep the core busy. ``weighted``
    # False: W is all ones and is not read (multiplying by 1.0 is exact: the same sums).
    wl1 = wl + 1
    for x in range(wl):
        prev[x] = 1.0
    for x in range(wl1):
        I2[2 * (o + x)] = 0.0
        I2[2 * (o + x) + 1] = 0.0
    y = 0
    while y + 4 <= hl:
        r0 = r1 = r2 = r3 = 1.0
        a0 = a1 = a2 = a3 = 0.0
        b0 = b1 = b2 = b3 = 0.0
        d0 = o + y * wl1
        d1, d2, d3 = d0 + wl1, d0 + 2 * wl1, d0 + 3 * wl1
        up = 2 * d0
        i1, i2, i3, i4 = up + 2 * wl1, up + 4 * wl1, up + 6 * wl1, up + 8 * wl1
        I2[i1] = I2[i1 + 1] = I2[i2] = I2[i2 + 1] = I2[i3] = I2[i3 + 1] = I2[i4] = I2[i4 + 1] = 0.0
        q0 = p0 + y * w
        q1, q2, q3 = q0 + w, q0 + 2 * w, q0 + 3 * w
        for x in range(wl):
            r0 *= D[d0 + x]
            r1 *= D[d1 + x]
            r2 *= D[d2 + x]
            r3 *= D[d3 + x]
            p_0 = r0 * prev[x]
            p_1 = r1 * p_0
            p_2 = r2 * p_1
            p_3 = r3 * p_2
            prev[x] = p_3
            v0 = 1.0 - p_0
            v1 = 1.0 - p_1
            v2 = 1.0 - p_2
            v3 = 1.0 - p_3
            if weighted:
                v0 *= W[q0 + x]
                v1 *= W[q1 + x]
                v2 *= W[q2 + x]
                v3 *= W[q3 + x]
            a0 += v0
            a1 += v1
            a2 += v2
            a3 += v3
            b0 += v0 * B[q0 + x]
            b1 += v1 * B[q1 + x]
            b2 += v2 * B[q2 + x]
            b3 += v3 * B[q3 + x]
            j = 2 * (x + 1)
            s0 = I2[up + j] + a0
            t0 = I2[up + j + 1] + b0
            I2[i1 + j] = s0
            I2[i1 + j + 1] = t0
            s1 = s0 + a1
            t1 = t0 + b1
            I2[i2 + j] = s1
            I2[i2 + j + 1] = t1
            s2 = s1 + a2
            t2 = t1 + b2
            I2[i3 + j] = s2
            I2[i3 + j + 1] = t2
            I2[i4 + j] = s2 + a3
            I2[i4 + j + 1] = t2 + b3
        y += 4
    while y < hl:
        r = 1.0
        ra = 0.0
        rba = 0.0
        row = 2 * (o + (y + 1) * wl1)
        up = 2 * (o + y * wl1)
        I2[row] = 0.0
        I2[row + 1] = 0.0
        pix = p0 + y * w
        for x in range(wl):
            r *= D[o + y * wl1 + x]
            pr = r * prev[x]
            prev[x] = pr
            a = 1.0 - pr
            if weighted:
                a *= W[pix + x]
            ra += a
            rba += a * B[pix + x]
            j = 2 * (x + 1)
            I2[row + j] = I2[up + j] + ra
            I2[row + j + 1] = I2[up + j + 1] + rba
        y += 1


@njit(cache=True, boundscheck=False)
def _frame_constants(c, B, W, hw, px_off, ii_off, boxes, D, ones, RW, RB, SB):  # pragma: no cover - compiled
    # constant per frame for camera c: |W R_ck|, |W B R_ck| and |W B| (integral images built in D's storage of c)
    h, w = hw[c, 0], hw[c, 1]
    o, w1 = ii_off[c], w + 1
    for pass_ in range(2):
        _integral(ones if pass_ == 0 else B, W, h, w, px_off[c], D, o)
        for k in range(boxes.shape[1]):
            x0 = boxes[c, k, 0]
            if x0 < 0:
                continue
            v = _box_sum(D, o, w1, x0, boxes[c, k, 1], boxes[c, k, 2], boxes[c, k, 3])
            if pass_ == 0:
                RW[c, k] = v
            else:
                RB[c, k] = v
    SB[c] = D[o + (h + 1) * w1 - 1]


@njit(cache=True, boundscheck=False)
def _corner_indices(c, boxes, o, X0, Y0, X1, Y1, corners):  # pragma: no cover - compiled
    # corners[c, k] = positions of box k's four corners (top-left, top-right, bottom-left, bottom-right; exclusive
    # right and bottom) in the (Y1 - Y0 + 2) x (X1 - X0 + 2) integral image of the region [X0, X1] x [Y0, Y1]
    # stored at o, clamped into it; -1 where the box is not visible
    wl, hl = X1 - X0 + 1, Y1 - Y0 + 1
    wl1 = wl + 1
    for k in range(boxes.shape[1]):
        x0 = boxes[c, k, 0]
        if x0 < 0:
            corners[c, k, 0] = -1
            continue
        lx0 = min(max(x0 - X0, 0), wl)
        lx1 = min(max(boxes[c, k, 2] + 1 - X0, 0), wl)
        ly0 = min(max(boxes[c, k, 1] - Y0, 0), hl)
        ly1 = min(max(boxes[c, k, 3] + 1 - Y0, 0), hl)
        corners[c, k, 0] = o + ly0 * wl1 + lx0
        corners[c, k, 1] = o + ly0 * wl1 + lx1
        corners[c, k, 2] = o + ly1 * wl1 + lx0
        corners[c, k, 3] = o + ly1 * wl1 + lx1


@njit(cache=True, boundscheck=False, error_model="numpy")
def _camera_terms(c, B, W, weighted, hw, px_off, ii_off, boxes, q, t_remove, active, n_active, active_changed,
                  evaluate, n_eval, D, I2, prev, RW, RB, SB, region, corners, inv_sigma,
                  acc):  # pragma: no cover - compiled
    # acc[c, k] = [Psi(B_c, Abar_c^{k,1}) - Psi(B_c, Abar_c^{k,0})] / sigma for every location k of
    # evaluate[:n_eval]. active[:n_active]: the locations in the synthetic image (q_k >= cut), increasing k;
    # active_changed: that set changed since the last call. Reads q, t_remove and the lists; writes only camera
    # c's storage (D and I2 at its offsets, prev[c], region[c], corners[c], acc[c]): the cameras can run in
    # parallel.
    h, w = hw[c, 0], hw[c, 1]
    o, po = ii_off[c], px_off[c]
    # 1. the region [X0, X1] x [Y0, Y1] covered by some box in the synthetic image (Abar = 0 elsewhere, so the
    # integral images need only cover it: outside, they are its values clamped to its edges); it can change only
    # where the set of active locations did, and the corner positions are recomputed where it changed
    if active_changed:
        X0, Y0, X1, Y1 = w, h, -1, -1
        for i in range(n_active):
            k = active[i]
            x0 = boxes[c, k, 0]
            if x0 < 0:
                continue
            X0 = min(X0, x0)
            Y0 = min(Y0, boxes[c, k, 1])
            X1 = max(X1, boxes[c, k, 2])
            Y1 = max(Y1, boxes[c, k, 3])
        if X1 < 0:
            X0, Y0, X1, Y1 = 0, 0, -1, -1
        if X0 != region[c, 0] or Y0 != region[c, 1] or X1 != region[c, 2] or Y1 != region[c, 3]:
            region[c, 0], region[c, 1], region[c, 2], region[c, 3] = X0, Y0, X1, Y1
            _corner_indices(c, boxes, o, X0, Y0, X1, Y1, corners)
    X0, Y0, X1, Y1 = region[c, 0], region[c, 1], region[c, 2], region[c, 3]
    wl, hl = X1 - X0 + 1, Y1 - Y0 + 1
    wl1 = wl + 1
    # difference array (local, (hl + 1) x wl1) of prod_k (1 - q_k R_ck): each active box scales its four corners,
    # in increasing k (the same products as a pass over all locations). (Resetting D to 1 inside the pass instead
    # of this fill was 15 % slower per solve at 200 x 200: the pass is bound by its stores.)
    for i in range(o, o + (hl + 1) * wl1):
        D[i] = 1.0
    for i in range(n_active):
        k = active[i]
        i00 = corners[c, k, 0]
        if i00 < 0:
            continue
        f = 1.0 - q[k]
        g = t_remove[k]  # 1 / f
        D[i00] *= f
        D[corners[c, k, 1]] *= g
        D[corners[c, k, 2]] *= g
        D[corners[c, k, 3]] *= f
    # 2. running 2-D product -> Abar = 1 - prod; integral images of W Abar and W B Abar in the same pass,
    # interleaved so that one box corner of both is one cache line
    _abar_pass(D, W, B, I2, prev[c], o, wl, hl, po + Y0 * w + X0, w, weighted)
    last = 2 * (o + (hl + 1) * wl1 - 1)
    SA, SBA, sb = I2[last], I2[last + 1], SB[c]
    # 3. per location: pseudo-distance with the location present and absent (its box sums: four look-ups each)
    for i in range(n_eval):
        k = evaluate[i]
        i00 = corners[c, k, 0]
        if i00 < 0:
            continue
        i00 *= 2
        i01 = 2 * corners[c, k, 1]
        i10 = 2 * corners[c, k, 2]
        i11 = 2 * corners[c, k, 3]
        rA = I2[i11] - I2[i01] - I2[i10] + I2[i00]
        rBA = I2[i11 + 1] - I2[i01 + 1] - I2[i10 + 1] + I2[i00 + 1]
        rW, rB = RW[c, k], RB[c, k]
        t = t_remove[k]
        in0 = rW - (rW - rA) * t
        if in0 < 0.0:
            in0 = 0.0
        inb0 = rB - (rB - rBA) * t
        if inb0 < 0.0:
            inb0 = 0.0
        if inb0 > in0:
            inb0 = in0
        a1 = SA - rA + rW
        ba1 = SBA - rBA + rB
        a0 = SA - rA + in0
        ba0 = SBA - rBA + inb0
        # psi1 - psi0 = n1 / d1 - n0 / d0, over one division
        d1 = max(a1, 1.0)
        d0 = max(a0, 1.0)
        acc[c, k] = ((sb + a1 - 2.0 * ba1) * d0 - (sb + a0 - 2.0 * ba0) * d1) * inv_sigma / (d1 * d0)


def _solve_py(B, W, weighted, hw, px_off, ii_off, boxes, q, D, I2, log_prior_ratio, inv_sigma, max_iter, damping,
              tol, ignored_below, q_max, prior):  # pragma: no cover - compiled
    n_cam, K = boxes.shape[0], boxes.shape[1]
    ones = np.ones(B.shape[0], B.dtype)
    RW = np.zeros((n_cam, K))
    RB = np.zeros((n_cam, K))
    SB = np.zeros(n_cam)
    for c in prange(n_cam):
        _frame_constants(c, B, W, hw, px_off, ii_off, boxes, D, ones, RW, RB, SB)
    # one row per camera, summed in camera order after the parallel loop: the same sums on any number of threads
    acc = np.zeros((n_cam, K))
    prev = np.empty((n_cam, hw[:, 1].max()))
    # each camera's current region of the synthetic image and its boxes' corner positions in it (none yet)
    region = np.full((n_cam, 4), -2, dtype=np.int64)
    corners = np.empty((n_cam, K, 4), dtype=np.int32)  # int32: half the bytes read per location
    # a location whose last target marginal was below 1e-8 is dormant: damped towards 0 without evaluation,
    # evaluated again on every REFRESH-th iteration (and before convergence is declared)
    skip = np.zeros(K, dtype=np.bool_)
    cut = max(ignored_below, Q_NEGLIGIBLE * prior)
    # 1 / (1 - q_k) removes location k from the synthetic image (1 where it is left out of it); kept up to date
    # by the update below, with the lists (increasing k) of the locations in the synthetic image (q_k >= cut)
    # and of those evaluated next (not dormant): the cameras' loops visit only these
    t_remove = np.ones(K)
    active = np.empty(K, dtype=np.int64)
    evaluate = np.arange(K)
    n_active = 0
    for k in range(K):
        if q[k] >= cut:
            t_remove[k] = 1.0 / (1.0 - q[k])
            active[n_active] = k
            n_active += 1
    n_eval = K
    active_changed = True
    converged = False
    full = True
    it = 0
    while it < max_iter:
        it += 1
        if it % REFRESH == 0 or it == max_iter:
            full = True
        if full:
            skip[:] = False
            for k in range(K):
                evaluate[k] = k
            n_eval = K
        for c in prange(n_cam):
            _camera_terms(c, B, W, weighted, hw, px_off, ii_off, boxes, q, t_remove, active, n_active,
                          active_changed, evaluate, n_eval, D, I2, prev, RW, RB, SB, region, corners, inv_sigma, acc)
        # 4. damped fixed-point update; converged when no marginal moved by more than tol relative to
        # max(q_k, prior) (an absolute bound would stop at once on fine grids, where every q_k is small)
        moved = False
        active_changed = False
        n_active = 0
        n_eval = 0
        for k in range(K):
            qk = q[k]
            if skip[k]:
                qn = qk * damping  # its target is below 1e-8: the damped update without evaluating it
            else:
                s = 0.0
                for c in range(n_cam):
                    s += acc[c, k]  # 0 where the location is not visible in camera c
                e = log_prior_ratio[k] + s
                if e > 700.0:
                    e = 700.0
                qn = damping * qk + (1.0 - damping) * (1.0 / (1.0 + np.exp(e)))
                if qn > q_max:
                    qn = q_max
                if abs(qn - qk) > tol * max(qk, prior):
                    moved = True
                if e > E_DORMANT:
                    skip[k] = True
                else:
                    evaluate[n_eval] = k  # n_eval <= k: the list is rewritten in place behind the loop
                    n_eval += 1
            q[k] = qn
            if qn >= cut:
                t_remove[k] = 1.0 / (1.0 - qn)
                active[n_active] = k
                n_active += 1
                active_changed |= qk < cut
            else:
                t_remove[k] = 1.0
                active_changed |= qk >= cut
        if not moved:
            if full:
                converged = True
                break
            full = True  # confirm on an iteration that evaluates every location
        else:
            full = False
    return it, converged


# One source, two kernels: prange is range in the serial one. The parallel one runs the cameras on numba's
# threads; each camera writes only its own rows, summed in camera order, so both give the same bits. It is
# compiled on first use (not cached: its cache entry would share the serial one's name).
# error_model="numpy" (here and in _camera_terms): no zero-division test before each division. None can divide
# by zero (denominators >= 1 pixel, 1 - q_k >= 1 - Q_MAX, 1 + exp(e) >= 1, REFRESH > 0), so the results are the
# same bits; the test was a branch in the two loops over the locations (about 1.1x per solve at 200 x 200).
_solve = njit(cache=True, boundscheck=False, error_model="numpy")(_solve_py)
_solve_parallel = njit(boundscheck=False, parallel=True, error_model="numpy")(_solve_py)
