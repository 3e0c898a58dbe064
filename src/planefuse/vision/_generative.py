"""The generative camera sensor model on the plane stack: mean-field marginals -> per-plane evidence.

Where the per-cell model (:class:`CameraFusion`) scores every cell of every plane on its own, this one explains
the whole foreground image of every camera at once (Fleuret et al. 2008; :mod:`planefuse.occupancy`): a person
standing on ground location k (a cell of the stack's grid) is a cylinder of radius ``radius_m`` across the
stack's height bands, its silhouette in camera c the box ``R_ck`` (:func:`silhouettes_from_cameras`), and the
mean-field posterior marginals ``q_k = P(X_k = 1 | B)`` of all locations explain each foreground pixel once.
Its output on the stack, for the Bayesian occupancy filter (docs/cameras.md, "Generative sensor model")::

    eps      = people_per_m2 * cell_size_m^2                        prior of a location
    P_occ(X) = 1 - prod_{k: |x_k - X| <= radius_m} (1 - q_k)         a body covers cell X (some person within r)
    P_0(X)   = 1 - (1 - eps)^{n_disc(X)}                            the same before the images (disc cut at the edge)
    L_l(X)   = clip(logit P_occ(X) - logit P_0, +-max_log_odds)     on every plane l inside the person's volume

i.e. the posterior log-odds of the cell minus its prior log-odds: the log-likelihood ratio the images carry
about the cell, in the form the BOF update adds (``bof_update``: log-odds of the evidence). With
``evidence_prior`` ``p_e`` the reference is ``logit p_e`` instead; with ``hidden_unknown`` as well, log-odds
between ``logit P_0`` and ``logit p_e`` give none and the others are measured against the nearer one::

    L_l(X)   = clip(min(l - lo, 0) + max(l - hi, 0), +-max_log_odds),  l = logit P_occ(X),
               lo, hi = min, max(logit P_0, logit p_e)

A person hidden behind others in every view changes no synthetic image, so the images leave his locations at
the prior (``q = eps``, ``l = logit P_0``): unknown, where ``logit p_e`` alone would count it as evidence against
a body at every frame. Cells no camera
sees, and planes outside the person's height range, get 0 (unknown). People on the ground are the local
maxima of the expected number of people within ``radius_m`` of a cell, ``M(X) = sum_{disc} q_k``, above
``detection_mass``, at least ``PersonParams.nms_radius_m`` apart, placed at the q-weighted centroid of their disc.

Tracked people as the prior (``track_prior_ratio`` > 1): the locations within ``track_prior_radius_m`` of a
tracked person's position predicted to the instant (:meth:`GenerativeCameraSensor.location_prior`) start from
``eps_k = ratio * eps``, so that where the images are ambiguous (a person half hidden, or in a foreground hole)
the explaining-away keeps the person the tracks expect rather than a ghost elsewhere. The filter already holds
what the tracks know, so the evidence must not count it again: it is measured against the reference moved by
the prior's own share, ``logit P_0(eps_k) - logit P_0(eps)`` per cell (``P_0`` as above with the per-location
priors), which gives exactly the evidence of the uniform prior where the images say nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import cv2
import numpy as np
from scipy import ndimage

from ..geometry import PinholeCamera
from ..grid import Evidence, GroundDetections, PlaneStack
from ..occupancy import GenerativeParams, MeanFieldSolver, PersonVolume, Silhouettes, silhouettes_from_cameras
from ._persons import _disc as _disc_mask

__all__ = ["GenerativeCameraSensor", "GenerativeSensorParams", "detection_evidence_prior"]


@dataclass(frozen=True)
class GenerativeSensorParams:
    """Parameters of the generative camera sensor model on a plane stack.

    ``sigma``, ``radius_m`` and ``detection_mass`` were chosen on the simulated default scene seen by 2 of its 4
    cameras, seeds 1-3 (KNN foreground, MODA at 0.5 m; docs/results.md), among sigma 0.003-0.03, radius
    0.15-0.3 m, mass 0.2-0.5, density 0.05-0.2 per m^2.

    Attributes
    ----------
    people_per_m2 : float
        Prior density of people [1/m^2]; a location's prior is ``people_per_m2 * cell_size_m**2``.
    sigma : float
        Scale of the image pseudo-distance (:class:`~planefuse.occupancy.GenerativeParams` ``sigma``).
    radius_m : float
        Radius of the person's cylinder [m] (silhouettes, and the disc a person covers on the stack).
    height_range_m : tuple of (float, float) or None
        Bottom and top of the person's cylinder [m]; None = the stack's height bands.
    max_log_odds : float
        Bound on the evidence of one instant per cell (so that one frame cannot saturate the filter).
    detection_mass : float
        A person is reported where the expected number of people within ``radius_m`` reaches this.
    foreground_threshold : float or None
        Foreground likelihoods at or above this are foreground (1), the rest background (0), as POM's binary
        masks; None keeps the likelihoods. A subtractor's floor (0.02 on every background pixel) otherwise
        sums, over a whole image, to more than the silhouettes of several people.
    evidence_prior : float or None
        What the evidence is measured against: None = the model's prior ``P_0`` (module notes: the likelihood
        ratio the images carry); p in (0, 1) = ``logit(p)`` instead, reading the marginals as calibrated
        posteriors, so that a cell the explaining-away leaves below p is evidence *against* a body. With two
        cameras, ghosts left at q ~ 0.3 frame after frame otherwise gain evidence at every frame and the filter
        accumulates them (EPFL terrace, frames 0-1499: filtered MODA 0.13 with None, 0.64 with 0.5;
        docs/results.md).
    hidden_unknown : bool
        With ``evidence_prior`` set: log-odds between the model's prior ``P_0`` and ``evidence_prior`` give no
        evidence (module notes), so that a cell the images cannot see into -- a person hidden behind others in
        every view, whose silhouettes change no synthetic image, keeps ``q`` at the prior -- is unknown to the
        filter rather than evidence against a body; log-odds outside that band are measured against the
        nearer of the two. False: everything against ``evidence_prior``.
    max_iterations : int
        Most mean-field iterations per instant (:class:`~planefuse.occupancy.GenerativeParams`
        ``max_iterations``). With its relative tolerance the solver rarely stops before them on real images (EPFL
        terrace: 97 % of the instants at 100), so they set its cost: one instant of two 360x288 cameras on a
        75 x 110 grid costs ~0.77 ms per iteration (docs/benchmarks.md).
    track_prior_ratio : float
        People tracked up to an instant as what is known before its images (module notes, "Tracked people as the
        prior"): a location within ``track_prior_radius_m`` of a tracked person's predicted position has this
        times the prior ``eps``; 1 = the same prior everywhere (every instant on its own).
    track_prior_radius_m : float
        Radius [m] of the disc around each tracked person's predicted position where ``track_prior_ratio`` applies.
    """

    people_per_m2: float = 0.05
    sigma: float = 0.005
    radius_m: float = 0.2
    height_range_m: tuple[float, float] | None = None
    max_log_odds: float = 6.0
    detection_mass: float = 0.4
    foreground_threshold: float | None = 0.5
    evidence_prior: float | None = None
    hidden_unknown: bool = False
    max_iterations: int = GenerativeParams.max_iterations
    track_prior_ratio: float = 1.0
    track_prior_radius_m: float = 0.7

    def __post_init__(self) -> None:
        if not (np.isfinite(self.track_prior_ratio) and self.track_prior_ratio >= 1.0):
            raise ValueError(f"GenerativeSensorParams.track_prior_ratio must be finite and >= 1, got "
                             f"{self.track_prior_ratio}")
        for name in ("people_per_m2", "sigma", "radius_m", "max_log_odds", "detection_mass", "track_prior_radius_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"GenerativeSensorParams.{name} must be finite and > 0, got {v}")
        if not (isinstance(self.max_iterations, (int, np.integer)) and self.max_iterations >= 1):
            raise ValueError(f"GenerativeSensorParams.max_iterations must be an integer >= 1, got "
                             f"{self.max_iterations!r}")
        if self.evidence_prior is not None and not 0.0 < self.evidence_prior < 1.0:
            raise ValueError(f"GenerativeSensorParams.evidence_prior must be in (0, 1) or None, got {self.evidence_prior}")

    def person(self, stack: PlaneStack) -> PersonVolume:
        """The person's volume on ``stack``."""
        if self.height_range_m is None:
            return PersonVolume.from_stack(stack, radius_m=self.radius_m)
        return PersonVolume(radius_m=self.radius_m, height_range_m=self.height_range_m)

    def solver_params(self, stack: PlaneStack) -> GenerativeParams:
        """Solver parameters with the prior of one location of ``stack``."""
        prior = self.people_per_m2 * stack.cell_size_m ** 2
        if not 0.0 < prior * self.track_prior_ratio < 0.5:
            raise ValueError(f"people_per_m2 {self.people_per_m2} with {stack.cell_size_m} m cells (and "
                             f"track_prior_ratio {self.track_prior_ratio}) gives a location prior of "
                             f"{prior * self.track_prior_ratio}; expected below 0.5")
        return GenerativeParams(prior=prior, sigma=self.sigma, max_iterations=int(self.max_iterations))


def detection_evidence_prior(detection_mass: float, column_threshold: float) -> float:
    """The ``evidence_prior`` that makes the filter's evidence agree with the per-frame detector.

    The detector reports a person where the expected number of people within ``radius_m``, ``M = sum q_k``,
    reaches ``detection_mass`` ``m``; there ``P_occ = 1 - prod (1 - q_k) >= 1 - exp(-M) >= P* = 1 - exp(-m)``.
    Measured against ``p_e``, one frame's evidence at that cell is at least ``logit P* - logit p_e``; the
    clustering (:func:`planefuse.tracking.column_log_odds`) reports a column whose mean log-odds above the
    filter's prior reaches ``column_threshold`` ``T``, which one frame's evidence on a cell at the prior is. So
    ``p_e = logistic(logit P* - T)``: a person the detector just reports in one frame is, on a cell at the
    prior, a cluster just at the threshold; a weaker disc gives less, evidence against only where
    ``P_occ < p_e``. A ghost the explaining-away leaves at ``q ~ 0.3`` for several frames is evidence for a
    body (below ``T`` in one frame, but the filter accumulates it): the model must explain most ghosts away
    (EPFL terrace, two cameras, four planes: filtered precision 0.89 -> 0.80 for recall 0.46 -> 0.69 on the
    held-out frames; on the ground plane alone, which cannot, precision 0.16; docs/results.md).

    Against even odds (``p_e = 0.5``) instead, every person the detector reports with ``P_occ < 0.5`` (mass below
    ~0.7) is evidence *against*, and one frame needs ``P_occ >= logistic(T)`` (0.88 at ``T = 2``) to make a
    cluster: the filtered system then misses people the detector finds (EPFL terrace, docs/results.md).

    Parameters
    ----------
    detection_mass : float
        ``GenerativeSensorParams.detection_mass`` (> 0), expected people within ``radius_m``.
    column_threshold : float
        ``ClusterParams.threshold``, mean capped log-odds per observed body plane.

    Returns
    -------
    float
        ``p_e`` in (0, 1).
    """
    if not (np.isfinite(detection_mass) and detection_mass > 0):
        raise ValueError(f"detection_mass must be finite and > 0, got {detection_mass}")
    if not np.isfinite(column_threshold):
        raise ValueError(f"column_threshold must be finite, got {column_threshold}")
    p_star = -np.expm1(-float(detection_mass))
    logit = np.log(p_star) - np.log1p(-p_star) - float(column_threshold)
    return float(1.0 / (1.0 + np.exp(-logit)))


def _logit_occupied(log_free: np.ndarray) -> np.ndarray:
    """``logit(1 - e^a)`` of ``a = log P(no person within r)``, with expm1 for the small-mass cells."""
    log_free = np.minimum(log_free, -1e-300)
    return np.log(-np.expm1(log_free)) - log_free


def _likelihood(image) -> np.ndarray:
    """Foreground likelihood in [0, 1] of a bool, uint8 (0..255) or float image."""
    a = np.asarray(image)
    return a / 255.0 if a.dtype == np.uint8 else a


class GenerativeCameraSensor:
    """The generative sensor model of C calibrated cameras on a plane stack (see module notes).

    Parameters
    ----------
    cameras : sequence of PinholeCamera
        Calibrated cameras (lens distortion included: frames are raw).
    stack : PlaneStack
        Ground locations are the cells of its grid.
    params : GenerativeSensorParams
    ignore_masks : sequence of (bool ndarray (height_px, width_px) or None), optional
        Per camera, pixels that are not scene evidence (no evidence either way).
    names : sequence of str, optional
    """

    def __init__(self, cameras: Sequence[PinholeCamera], stack: PlaneStack,
                 params: GenerativeSensorParams = GenerativeSensorParams(),
                 ignore_masks: Sequence[np.ndarray | None] | None = None,
                 names: Sequence[str] | None = None) -> None:
        self.cameras = list(cameras)
        self.stack = stack
        self.params = params
        self.names = list(names) if names is not None else [c.name for c in self.cameras]
        self.person = params.person(stack)
        C = len(self.cameras)
        masks = [None] * C if ignore_masks is None else list(ignore_masks)
        if len(masks) != C:
            raise ValueError(f"ignore_masks: expected {C} entries (None where absent), got {len(masks)}")
        self._observed = []
        for cam, m in zip(self.cameras, masks):
            shape = (cam.intrinsics.height_px, cam.intrinsics.width_px)
            if m is not None and np.shape(m) != shape:
                raise ValueError(f"{cam.name}: ignore mask is {np.shape(m)}, the image is {shape}")
            self._observed.append(np.ones(shape, bool) if m is None else ~np.asarray(m, bool))
        self._blind = [np.zeros(s.shape, bool) for s in self._observed]
        self._disc = _disc_mask(params.radius_m / stack.cell_size_m).astype(np.float64)
        self._solver_params = params.solver_params(stack)
        # the prior's log P(no person within r) per cell, with the same truncation of the disc at the grid's edge
        log_free_model = cv2.filter2D(np.full((stack.ny, stack.nx), np.log1p(-self._solver_params.prior)),
                                      cv2.CV_64F, self._disc, borderType=cv2.BORDER_CONSTANT)
        # what the evidence is measured against (logit of P_0 or of evidence_prior), as the band of logit P_occ
        # that gives none: one value, or, hidden_unknown, everything between the two
        ref_model = _logit_occupied(log_free_model)
        self._logit_p0 = ref_model
        self._ref = (ref_model, ref_model)
        if params.evidence_prior is not None:
            ref = _logit_occupied(np.full((stack.ny, stack.nx), np.log1p(-params.evidence_prior)))
            self._ref = (np.minimum(ref, ref_model), np.maximum(ref, ref_model)) if params.hidden_unknown else (ref, ref)
        band_mid = 0.5 * (np.asarray(stack.band_edges_m[:-1]) + np.asarray(stack.band_edges_m[1:]))
        lo, hi = self.person.height_range_m
        self._planes = (band_mid >= lo) & (band_mid <= hi)
        self._set_silhouettes(silhouettes_from_cameras(self.cameras, stack, self.person))
        self.last_marginals: np.ndarray | None = None
        self._centres: np.ndarray | None = None

    def _set_silhouettes(self, sil: Silhouettes) -> None:
        self.silhouettes = sil
        self._solver = MeanFieldSolver(sil, self._solver_params)
        self._seen = sil.visible.any(axis=0).reshape(self.stack.ny, self.stack.nx)

    @property
    def n_cameras(self) -> int:
        """Number of cameras C."""
        return len(self.cameras)

    @property
    def solver_params(self) -> GenerativeParams:
        """The mean-field solver's parameters (prior of one location of the stack)."""
        return self._solver_params

    @property
    def blind_cameras(self) -> list[str]:
        """Cameras in which no location has a silhouette."""
        return [n for n, v in zip(self.names, self.silhouettes.visible) if not v.any()]

    def marginals(self, foregrounds: Sequence[np.ndarray | None], prior: np.ndarray | None = None) -> np.ndarray:
        """Posterior marginals ``q`` (ny, nx) of one instant; a camera with no frame (None) gives no evidence.
        ``prior`` (ny, nx): each location's prior (default: the model's ``eps`` everywhere)."""
        if len(foregrounds) != self.n_cameras:
            raise ValueError(f"expected {self.n_cameras} foreground images (None for missing), got {len(foregrounds)}")
        thr = self.params.foreground_threshold
        fg = [np.zeros(o.shape) if f is None else f if thr is None else _likelihood(f) >= thr
              for f, o in zip(foregrounds, self._observed)]
        obs = [b if f is None else o for f, o, b in zip(foregrounds, self._observed, self._blind)]
        q = self._solver.solve(fg, obs, prior=None if prior is None else np.ravel(prior)).marginals
        q = q.reshape(self.stack.ny, self.stack.nx)
        self.last_marginals = q
        return q

    def log_odds_from_marginals(self, q: np.ndarray, prior: np.ndarray | None = None) -> np.ndarray:
        """Per-plane evidence (L, ny, nx) float32 from marginals (ny, nx) (module notes); ``prior`` (ny, nx): the
        locations' priors the marginals were solved with (default: ``eps``), whose own share of ``logit P_occ``
        (``logit P_0`` of that prior minus that of ``eps``) is taken out of the evidence."""
        log_free = cv2.filter2D(np.log1p(-np.clip(q, 0.0, 1.0 - 1e-12)), cv2.CV_64F, self._disc,
                                borderType=cv2.BORDER_CONSTANT)
        lo, hi = self._ref
        if prior is not None:
            shift = _logit_occupied(cv2.filter2D(np.log1p(-np.asarray(prior, np.float64)), cv2.CV_64F, self._disc,
                                                 borderType=cv2.BORDER_CONSTANT)) - self._logit_p0
            lo, hi = lo + shift, hi + shift
        logit_occ = _logit_occupied(log_free)
        ev = np.minimum(logit_occ - lo, 0.0) + np.maximum(logit_occ - hi, 0.0)
        ev = np.where(self._seen, np.clip(ev, -self.params.max_log_odds, self.params.max_log_odds), 0.0)
        out = np.zeros(self.stack.shape, np.float32)
        out[self._planes] = ev.astype(np.float32)
        return out

    def location_prior(self, xy_m) -> np.ndarray | None:
        """Each location's prior (ny, nx) given people tracked at ``xy_m`` (N, 2) [m, world], predicted to the
        instant: ``eps * track_prior_ratio`` within ``track_prior_radius_m`` of any of them, ``eps`` elsewhere
        (module notes). None where that is ``eps`` everywhere (no one tracked, or ratio 1)."""
        p = self.params
        xy = np.asarray(xy_m, dtype=float).reshape(-1, 2)
        if p.track_prior_ratio == 1.0 or not len(xy):
            return None
        if not np.isfinite(xy).all():
            raise ValueError(f"tracked positions xy_m must be finite [m], got {xy.tolist()}")
        if self._centres is None:
            self._centres = self.stack.cell_centers_xy()
        d2 = ((self._centres[:, :, None, :] - xy[None, None]) ** 2).sum(axis=-1).min(axis=-1)
        eps = self._solver_params.prior
        return np.where(d2 <= p.track_prior_radius_m ** 2, eps * p.track_prior_ratio, eps)

    def evidence(self, foregrounds: Sequence[np.ndarray | None], time_s: float,
                 sensor: str = "cameras") -> Evidence:
        """The :class:`~planefuse.grid.Evidence` of one instant."""
        return Evidence(float(time_s), sensor, self.log_odds_from_marginals(self.marginals(foregrounds)))

    def detections(self, q: np.ndarray, time_s: float, nms_radius_m: float,
                   source: str = "cameras") -> GroundDetections:
        """People on the ground from marginals (ny, nx): peaks of the expected number of people within
        ``radius_m``, at least ``nms_radius_m`` apart."""
        mass = cv2.filter2D(q, cv2.CV_64F, self._disc, borderType=cv2.BORDER_CONSTANT)
        r_nms = nms_radius_m / self.stack.cell_size_m
        peak = ndimage.maximum_filter(mass, footprint=_disc_mask(r_nms), mode="constant", cval=-np.inf)
        iy, ix = np.nonzero((mass >= peak) & (mass >= self.params.detection_mass) & self._seen)
        order = np.argsort(-mass[iy, ix], kind="stable")
        iy, ix = iy[order], ix[order]
        keep = np.ones(len(iy), bool)
        for i in range(len(iy)):
            if keep[i]:
                keep[i + 1:] &= (iy[i + 1:] - iy[i]) ** 2 + (ix[i + 1:] - ix[i]) ** 2 > r_nms * r_nms
        iy, ix = iy[keep], ix[keep]
        r = self._disc.shape[0] // 2
        wq = cv2.copyMakeBorder(q, r, r, r, r, cv2.BORDER_CONSTANT, value=0.0)
        yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
        fy, fx = iy.astype(float), ix.astype(float)
        for i in range(len(iy)):
            w = wq[iy[i]:iy[i] + 2 * r + 1, ix[i]:ix[i] + 2 * r + 1] * self._disc
            fy[i] += (w * yy).sum() / w.sum()
            fx[i] += (w * xx).sum() / w.sum()
        n = len(iy)
        return GroundDetections(float(time_s), self.stack.xy_from_index(fy, fx).reshape(-1, 2),
                                np.clip(mass[iy, ix], 0.0, 1.0), np.full(n, self.person.height_range_m[1]), source)
