r"""People's appearance from every camera that sees them: colour descriptors, their distance, per-track models.

A person standing at ground position ``p`` (world XY [m]) is seen by camera ``c`` in the box of the projected person
volume (:func:`planefuse.occupancy.silhouettes_from_cameras`, a vertical cylinder; a person detector's matched box
can be given instead, :func:`describe_boxes`). The descriptor of that view is two colour histograms, of the upper
body (rows ``upper_rows`` of the box, the torso) and of the lower body (``lower_rows``, the legs), over the central
``strip_fraction`` of the box's width (the cylinder's box is wider than the body; the strip holds mostly the
person). Each histogram has two parts that sum to 1 together:

* *chromatic* pixels (HSV saturation ``S >= min_saturation`` and value ``V >= min_value``): a hue x saturation
  histogram (``hue_bins`` x ``saturation_bins``). Hue and saturation are chromaticity: a change of the light's
  brightness (automatic exposure, clouds, shadow) leaves them, unlike the RGB levels;
* *achromatic* pixels (the others: black, grey and white clothes, whose hue is noise): a histogram of the value in
  ``value_bins`` bins (coarse, so that a brightness change moves little mass between bins).

The distance of two descriptors is the mean over the two body parts of the Hellinger distance::

    d(p, q) = mean_k sqrt(1 - sum_b sqrt(p_kb q_kb))          in [0, 1]

(0 for the same histograms, 1 for disjoint ones, symmetric; the Bhattacharyya coefficient ``sum sqrt(p q)`` of
normalised histograms is in [0, 1]).

Which views are used. A view is *not* taken where (``AppearanceParams``):

* the box is less than ``min_box_height_px`` tall, or not wholly inside the image (clipped: part of the person is
  outside the view);
* more than ``max_occluded_fraction`` of its strip is covered by the box of a person *nearer to the camera*
  (depth order from the geometry: the horizontal distance from the camera's centre to each person's ground
  position), the other people being the step's other person hypotheses and any extra occluder positions given
  (tracks predicted where no cluster is); the covered pixels are left out of the histograms of a view that is used;
* more than ``max_ignored_fraction`` of its strip lies in the camera's ignore regions (watermarks, masked areas;
  those pixels are left out too).

Per track and camera, the model is a running mean of the descriptors of the views taken
(:class:`TrackAppearance`): the plain mean of the first ``1 / update_rate`` views, then an exponential average at
``update_rate`` per view, so that a passer-by seen once in the track's box (a crossing, a wrong association) moves
the model by at most ``update_rate``; a view farther than ``update_max_distance`` from the model is not absorbed at
all. Colours differ between cameras (white balance, the side of the body seen), so a track's descriptor of camera
``c`` is compared with a cluster's descriptor of the same camera only; the track-to-cluster distance is the mean
over the cameras where both have one (NaN where none).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from .._params import check_fields, require
from ..geometry import PinholeCamera
from ..occupancy import PersonVolume, silhouettes_from_cameras

__all__ = ["AppearanceParams", "ViewDescriptors", "TrackAppearance", "AppearanceObserver", "describe_boxes",
           "colour_shares", "describe_positions", "descriptor_distance", "n_bins", "occluder_boxes_px"]


@dataclass(frozen=True)
class AppearanceParams:
    """How a person's appearance is read from a camera view (module docstring).

    Attributes
    ----------
    person_radius_m : float
        Radius [m] of the projected person cylinder whose box is the person's view.
    person_height_m : float
        Height [m] of that cylinder (from the ground).
    strip_fraction : float
        Central fraction of the box's width whose pixels are described, in (0, 1].
    upper_rows, lower_rows : (float, float)
        Rows of the upper and lower body as fractions of the box's height from its top, ``(start, end)``.
    hue_bins, saturation_bins, value_bins : int
        Bins of the chromatic (hue x saturation) and achromatic (value) histograms.
    min_saturation, min_value : int
        Chromatic pixels: HSV saturation and value at least these (0..255, OpenCV's 8-bit HSV).
    min_box_height_px : int
        A view whose box is shorter than this [px] is not used.
    max_occluded_fraction : float
        A view whose strip is covered by a nearer person's box beyond this fraction is not used.
    max_ignored_fraction : float
        A view whose strip lies in ignore regions beyond this fraction is not used.
    max_frame_age_s : float
        The frames used at a tracker step are the camera instant nearest the step, at most this far [s].
    """

    person_radius_m: float = 0.3
    person_height_m: float = 1.8
    strip_fraction: float = 0.5
    upper_rows: tuple[float, float] = (0.15, 0.5)
    lower_rows: tuple[float, float] = (0.5, 0.9)
    hue_bins: int = 12
    saturation_bins: int = 3
    value_bins: int = 4
    min_saturation: int = 50
    min_value: int = 40
    min_box_height_px: int = 20
    max_occluded_fraction: float = 0.3
    max_ignored_fraction: float = 0.3
    max_frame_age_s: float = 0.1

    def __post_init__(self) -> None:
        check_fields(self, person_radius_m=">0", person_height_m=">0", strip_fraction="(0,1]", hue_bins="int>=1",
                     saturation_bins="int>=1", value_bins="int>=1", min_box_height_px="int>=1",
                     max_occluded_fraction="[0,1]", max_ignored_fraction="[0,1]", max_frame_age_s=">=0")
        for name in ("upper_rows", "lower_rows"):
            a, b = getattr(self, name)
            require(0.0 <= a < b <= 1.0, self, name, f"must be (start, end) with 0 <= start < end <= 1, got {(a, b)}")
        for name in ("min_saturation", "min_value"):
            require(0 <= getattr(self, name) <= 255, self, name, f"must be in 0..255, got {getattr(self, name)}")

    def person(self) -> PersonVolume:
        """The person volume whose projected box is a view."""
        return PersonVolume(radius_m=self.person_radius_m, height_range_m=(0.0, self.person_height_m))


def n_bins(params: AppearanceParams) -> int:
    """Length ``B`` of one body part's histogram: ``hue_bins x saturation_bins + value_bins``."""
    return params.hue_bins * params.saturation_bins + params.value_bins


@dataclass(frozen=True)
class ViewDescriptors:
    """Descriptors of ``N`` people in ``C`` cameras.

    Attributes
    ----------
    hist : ndarray, shape (N, C, 2, B), float64
        Upper- and lower-body histograms (each sums to 1 where valid, 0 elsewhere).
    valid : ndarray, shape (N, C), bool
        Whether the view was taken (module docstring).
    """

    hist: np.ndarray
    valid: np.ndarray

    def __len__(self) -> int:
        return len(self.valid)

    @classmethod
    def empty(cls, n: int, n_cameras: int, params: AppearanceParams) -> "ViewDescriptors":
        """``n`` people with no view in any of ``n_cameras`` cameras."""
        return cls(np.zeros((n, n_cameras, 2, n_bins(params))), np.zeros((n, n_cameras), bool))


def descriptor_distance(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hellinger distance of descriptors ``p`` and ``q`` (..., 2, B) (broadcast), averaged over the body parts:
    ``mean_k sqrt(1 - sum_b sqrt(p_kb q_kb))`` in [0, 1] (module docstring); shape (...)."""
    p, q = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
    if p.shape[-2:] != q.shape[-2:] or p.shape[-2] != 2:
        raise ValueError(f"descriptors must have shape (..., 2, B) alike, got {p.shape} and {q.shape}")
    bc = np.sum(np.sqrt(np.maximum(p, 0.0) * np.maximum(q, 0.0)), axis=-1)
    return np.mean(np.sqrt(np.clip(1.0 - bc, 0.0, 1.0)), axis=-1)


def _hsv_codes(image_bgr: np.ndarray, params: AppearanceParams) -> np.ndarray:
    """Per pixel, its histogram bin (height_px, width_px) int: hue x saturation for chromatic pixels, then value."""
    img = np.asarray(image_bgr)
    if img.ndim == 2 or img.shape[-1] == 1:  # grey frames: every pixel achromatic
        v = img.reshape(img.shape[:2]).astype(np.int32)
        return params.hue_bins * params.saturation_bins + np.minimum(v * params.value_bins // 256,
                                                                     params.value_bins - 1)
    if img.dtype != np.uint8:
        raise ValueError(f"appearance frames must be uint8 BGR images, got dtype {img.dtype}")
    hsv = cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_BGR2HSV).astype(np.int32)
    h, s, v = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    chroma = (s >= params.min_saturation) & (v >= params.min_value)
    hb = np.minimum(h * params.hue_bins // 180, params.hue_bins - 1)
    s_lo = params.min_saturation
    sb = np.clip((s - s_lo) * params.saturation_bins // max(256 - s_lo, 1), 0, params.saturation_bins - 1)
    vb = np.minimum(v * params.value_bins // 256, params.value_bins - 1)
    return np.where(chroma, hb * params.saturation_bins + sb, params.hue_bins * params.saturation_bins + vb)


def describe_boxes(images: Sequence[np.ndarray | None], boxes_px: np.ndarray, depth_m: np.ndarray,
                   params: AppearanceParams, ignore_masks: Sequence[np.ndarray | None] | None = None,
                   n_described: int | None = None) -> ViewDescriptors:
    """Descriptors of the people whose views are ``boxes_px`` (module docstring).

    Parameters
    ----------
    images : sequence of C (ndarray (height_px, width_px, 3) uint8 BGR or None)
        One frame per camera (None: no frame, no view).
    boxes_px : ndarray, shape (C, K, 4), int
        Inclusive pixel boxes ``(x0, y0, x1, y1)`` per camera and person; -1 where not visible. A box that touches
        the image border is taken as clipped (not used).
    depth_m : ndarray, shape (C, K)
        Each person's distance from each camera [m] (the depth order: nearer people hide farther ones).
    params : AppearanceParams
    ignore_masks : sequence of C (bool ndarray (height_px, width_px) or None), optional
        Pixels that are not scene evidence.
    n_described : int, optional
        Describe the first ``n_described`` people only; the others are occluders only (default: all K).

    Returns
    -------
    ViewDescriptors
        ``n_described`` people.
    """
    boxes_px = np.asarray(boxes_px)
    C, K = boxes_px.shape[:2]
    if len(images) != C:
        raise ValueError(f"images: expected {C} entries (one per camera, None where absent), got {len(images)}")
    n = K if n_described is None else int(n_described)
    out = ViewDescriptors.empty(n, C, params)
    B = n_bins(params)
    for c, img in enumerate(images):
        if img is None or n == 0:
            continue
        H, W = img.shape[:2]
        ign = None if ignore_masks is None else ignore_masks[c]
        for i in range(n):
            x0, y0, x1, y1 = (int(v) for v in boxes_px[c, i])
            if x0 < 0 or y1 - y0 + 1 < params.min_box_height_px:
                continue
            if x0 <= 0 or y0 <= 0 or x1 >= W - 1 or y1 >= H - 1:
                continue  # clipped by the image border: part of the person out of view
            w = x1 - x0 + 1
            half = max(int(round(0.5 * params.strip_fraction * w)), 1)
            xc = (x0 + x1) // 2
            sx0, sx1 = max(xc - half, x0), min(xc + half, x1) + 1
            sy0, sy1 = y0 + int(params.upper_rows[0] * (y1 - y0 + 1)), y0 + int(params.lower_rows[1] * (y1 - y0 + 1))
            if sx1 <= sx0 or sy1 <= sy0:
                continue
            keep = np.ones((sy1 - sy0, sx1 - sx0), bool)
            for j in range(K):  # nearer people's boxes hide this one's pixels
                if j == i or boxes_px[c, j, 0] < 0 or not depth_m[c, j] < depth_m[c, i]:
                    continue
                bx0, by0, bx1, by1 = (int(v) for v in boxes_px[c, j])
                ox0, ox1, oy0, oy1 = max(bx0, sx0), min(bx1 + 1, sx1), max(by0, sy0), min(by1 + 1, sy1)
                if ox1 > ox0 and oy1 > oy0:
                    keep[oy0 - sy0:oy1 - sy0, ox0 - sx0:ox1 - sx0] = False
            if 1.0 - keep.mean() > params.max_occluded_fraction:
                continue
            if ign is not None:
                ignored = ign[sy0:sy1, sx0:sx1]
                if ignored.mean() > params.max_ignored_fraction:
                    continue
                keep &= ~ignored
            rows = np.arange(sy0, sy1)[:, None] - y0
            split = y0 + int(params.upper_rows[1] * (y1 - y0 + 1)) - y0
            lower_start = int(params.lower_rows[0] * (y1 - y0 + 1))
            patch = _hsv_codes(img[sy0:sy1, sx0:sx1], params)  # the strip's pixels only
            ok = True
            for k, part in enumerate((keep & (rows < split), keep & (rows >= lower_start))):
                h = np.bincount(patch[part], minlength=B).astype(float)
                if h.sum() < 4:  # too few pixels to describe this part
                    ok = False
                    break
                out.hist[i, c, k] = h / h.sum()
            if ok:
                out.valid[i, c] = True
            else:
                out.hist[i, c] = 0.0
    return out


def occluder_boxes_px(cameras: Sequence[PinholeCamera], boxes_m) -> tuple[np.ndarray, np.ndarray]:
    """Static occluders ``boxes_m`` (B, 6) ``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m, world] as seen by each
    camera: the pixel bounding box of each box's projected corners (C, B, 4) (-1 where a corner is behind the camera
    or the box is outside the image) and its depth (C, B) [m], the horizontal distance from the camera's centre to
    the nearest point of its footprint (what stands farther is hidden behind it)."""
    boxes = np.asarray(boxes_m, dtype=float).reshape(-1, 6)
    out = np.full((len(cameras), len(boxes), 4), -1, dtype=np.int32)
    depth = np.full((len(cameras), len(boxes)), np.inf)
    for c, cam in enumerate(cameras):
        w, h = cam.intrinsics.width_px, cam.intrinsics.height_px
        cx, cy = np.asarray(cam.center_world, float)[:2]
        for b, (x0, x1, y0, y1, z0, z1) in enumerate(boxes):
            corners = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)])
            uv = cam.project(corners)
            if not np.isfinite(uv).all():
                continue
            u0, v0 = np.floor(uv.min(axis=0)).astype(int)
            u1, v1 = np.ceil(uv.max(axis=0)).astype(int)
            if u1 < 0 or v1 < 0 or u0 > w - 1 or v0 > h - 1:
                continue
            out[c, b] = (max(u0, 0), max(v0, 0), min(u1, w - 1), min(v1, h - 1))
            depth[c, b] = np.hypot(cx - np.clip(cx, x0, x1), cy - np.clip(cy, y0, y1))
    return out, depth


def describe_positions(images: Sequence[np.ndarray | None], cameras: Sequence[PinholeCamera], xy_m: np.ndarray,
                       params: AppearanceParams, ignore_masks: Sequence[np.ndarray | None] | None = None,
                       occluders_xy_m: np.ndarray | None = None,
                       static: tuple[np.ndarray, np.ndarray] | None = None) -> ViewDescriptors:
    """Descriptors of people standing at ``xy_m`` (N, 2) [m, world] in every camera's frame (module docstring):
    their views are the boxes of the projected person cylinder (``params``); ``occluders_xy_m`` (M, 2) [m]: other
    people who may stand in front (not described); ``static``: static occluders' boxes (C, B, 4) and depths (C, B)
    (:func:`occluder_boxes_px`), which hide what stands behind them too. ``images``: one uint8 BGR frame per camera,
    None where absent."""
    xy = np.asarray(xy_m, dtype=float).reshape(-1, 2)
    occ = np.zeros((0, 2)) if occluders_xy_m is None else np.asarray(occluders_xy_m, dtype=float).reshape(-1, 2)
    everyone = np.concatenate([xy, occ])
    if not len(xy) or not len(cameras):
        return ViewDescriptors.empty(len(xy), len(cameras), params)
    boxes = silhouettes_from_cameras(cameras, everyone, params.person()).boxes_px
    depth = np.stack([np.hypot(*(everyone - np.asarray(cam.center_world, float)[:2]).T) for cam in cameras])
    if static is not None and static[0].shape[1]:
        boxes, depth = np.concatenate([boxes, static[0]], axis=1), np.concatenate([depth, static[1]], axis=1)
    return describe_boxes(images, boxes, depth, params, ignore_masks, n_described=len(xy))


@dataclass
class TrackAppearance:
    """One track's appearance per camera (module docstring): a running mean of the views taken.

    Attributes
    ----------
    hist : ndarray, shape (C, 2, B)
        The model per camera.
    count : ndarray, shape (C,)
        Views absorbed per camera (0: none yet).
    """

    hist: np.ndarray
    count: np.ndarray

    @classmethod
    def empty(cls, n_cameras: int, params: AppearanceParams) -> "TrackAppearance":
        return cls(np.zeros((n_cameras, 2, n_bins(params))), np.zeros(n_cameras))

    def distance(self, views: ViewDescriptors) -> np.ndarray:
        """Distance (K,) to each of ``views``' people: the mean over the cameras where both have a descriptor of
        :func:`descriptor_distance`; NaN where no camera has both."""
        both = views.valid & (self.count > 0)[None]
        d = descriptor_distance(self.hist[None], views.hist)  # (K, C)
        n = both.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n > 0, np.sum(np.where(both, d, 0.0), axis=1) / n, np.nan)

    def distance_to(self, other: "TrackAppearance") -> float:
        """Mean over the cameras where both models have views of :func:`descriptor_distance`; NaN where none."""
        both = (self.count > 0) & (other.count > 0)
        if not both.any():
            return float("nan")
        return float(np.mean(descriptor_distance(self.hist[both], other.hist[both])))

    def update(self, views: ViewDescriptors, k: int, rate: float, max_distance: float) -> None:
        """Absorb person ``k`` of ``views``: per camera where it has a view, ``m <- m + a (d - m)`` with
        ``a = max(1 / (count + 1), rate)``; a view farther than ``max_distance`` from an existing model is not
        absorbed."""
        for c in np.flatnonzero(views.valid[k]):
            d = views.hist[k, c]
            if self.count[c] > 0 and descriptor_distance(self.hist[c], d) > max_distance:
                continue
            a = max(1.0 / (self.count[c] + 1.0), rate)
            self.hist[c] += a * (d - self.hist[c])
            self.count[c] += 1

    def merged(self, other: "TrackAppearance") -> "TrackAppearance":
        """The two models pooled per camera, weighted by their counts."""
        n = self.count + other.count
        w = np.divide(self.count, n, out=np.zeros_like(n), where=n > 0)[:, None, None]
        return TrackAppearance(w * self.hist + (1 - w) * other.hist * (n > 0)[:, None, None], n)

    def summary(self, params: AppearanceParams, camera_names: Sequence[str] | None = None) -> str:
        """What the model holds, in words: per camera with views, their number and the main colour of the upper and
        lower body with its share, e.g. ``"c0 (31 views): upper blue 62 %, lower black 71 %"``."""
        names = list(camera_names) if camera_names is not None else [f"camera {c}" for c in range(len(self.count))]
        parts = []
        for c in np.flatnonzero(self.count > 0):
            body = []
            for k, what in enumerate(("upper", "lower")):
                shares = colour_shares(self.hist[c, k], params)
                name = max(shares, key=shares.get)
                body.append(f"{what} {name} {100 * shares[name]:.0f} %")
            parts.append(f"{names[c]} ({int(self.count[c])} views): " + ", ".join(body))
        return "; ".join(parts) or "no view"


#: Hue names by upper bound of OpenCV's 8-bit hue (0..180), in order.
_HUES = ((10, "red"), (22, "orange"), (35, "yellow"), (85, "green"), (100, "cyan"), (130, "blue"), (150, "purple"),
         (170, "pink"), (180, "red"))
_GREYS = ("black", "dark grey", "light grey", "white")


def colour_shares(hist: np.ndarray, params: AppearanceParams) -> dict[str, float]:
    """Share of a body part's histogram (B,) per colour name (hues of the chromatic bins, greys of the value bins)."""
    out: dict[str, float] = {}
    n_chroma = params.hue_bins * params.saturation_bins
    for b, w in enumerate(np.asarray(hist, float)):
        if b < n_chroma:
            hue = (b // params.saturation_bins + 0.5) * 180.0 / params.hue_bins
            name = next(n for hi, n in _HUES if hue < hi)
        else:
            v = b - n_chroma
            name = _GREYS[min(int(v * len(_GREYS) / params.value_bins), len(_GREYS) - 1)]
        out[name] = out.get(name, 0.0) + float(w)
    return out


class AppearanceObserver:
    """The appearance of each tracker step's clusters, from the latest camera frames (module docstring).

    The camera source hands it every instant's frames (:meth:`add_frames`; a few are kept, as the tracker steps
    at a batch released after the re-ordering window); the tracker asks, at each step, the descriptors of its
    clusters (:meth:`__call__`), with the confirmed tracks predicted to the step as further occluders.

    Parameters
    ----------
    cameras : sequence of C PinholeCamera
    params : AppearanceParams
    ignore_masks : sequence of C (bool ndarray or None), optional
    occluder_boxes_m : array_like, shape (B, 6), optional
        Known static occluders ``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m] (``SystemParams.occluder_boxes_m``):
        they hide the people behind them as nearer people do (:func:`occluder_boxes_px`).
    keep : int
        Camera instants kept.
    """

    def __init__(self, cameras: Sequence[PinholeCamera], params: AppearanceParams | None = None,
                 ignore_masks: Sequence[np.ndarray | None] | None = None, keep: int = 8,
                 occluder_boxes_m=None) -> None:
        self.cameras = list(cameras)
        self.params = params if params is not None else AppearanceParams()
        if ignore_masks is not None and len(ignore_masks) != len(self.cameras):
            raise ValueError(f"ignore_masks: expected {len(self.cameras)} entries (None where absent), "
                             f"got {len(ignore_masks)}")
        self.ignore_masks = ignore_masks
        self.static = (occluder_boxes_px(self.cameras, occluder_boxes_m)
                       if occluder_boxes_m is not None and len(occluder_boxes_m) else None)
        self.frames: deque[tuple[float, list]] = deque(maxlen=int(keep))

    @property
    def n_cameras(self) -> int:
        return len(self.cameras)

    def add_frames(self, time_s: float, images: Sequence[np.ndarray | None]) -> None:
        """Keep the frames of the camera instant ``time_s`` [s] (one per camera, None where absent)."""
        if len(images) != self.n_cameras:
            raise ValueError(f"appearance frames at t={time_s}: expected {self.n_cameras} images, got {len(images)}")
        self.frames.append((float(time_s), list(images)))

    def frames_at(self, time_s: float) -> list | None:
        """The kept frames nearest ``time_s`` [s] within ``max_frame_age_s``, else None."""
        best = None
        for t, imgs in self.frames:
            dt = abs(t - time_s)
            if dt <= self.params.max_frame_age_s + 1e-9 and (best is None or dt < best[0]):
                best = (dt, imgs)
        return None if best is None else best[1]

    def __call__(self, time_s: float, xy_m: np.ndarray, occluders_xy_m: np.ndarray | None = None) -> ViewDescriptors:
        """Descriptors (N people) of the clusters at ``xy_m`` (N, 2) [m] at the step ``time_s`` [s]; no view where
        no frame is near the step."""
        imgs = self.frames_at(time_s)
        if imgs is None:
            return ViewDescriptors.empty(len(xy_m), self.n_cameras, self.params)
        return describe_positions(imgs, self.cameras, xy_m, self.params, self.ignore_masks, occluders_xy_m,
                                  self.static)
