r"""Multi-person tracker on the BOF clusters: one constant-velocity Kalman filter per track.

Each track ``i`` carries the ground state ``x = (px, py, vx, vy)`` [m, m/s] in world XY and its covariance
``P``. The BOF and the clustering are its *sensor*: every cluster is a measurement of position and
velocity, ``z = (px, py, vx, vy)`` with ``H = I_4`` and the covariance::

    R = diag(s_p^2, s_p^2, s_v^2 + var_vx, s_v^2 + var_vy)

``s_p = position_std_m``, ``s_v = velocity_std_m_s``. The cluster's velocity ``v`` and variance ``var``
(:attr:`Clusters.velocity_var_m2_s2`: the BOF's velocity uncertainty in the cluster's cells plus the
spread of the cell velocities over the disc) are a *posterior* of the BOF, whose prior over velocities is
its uniform law on the hypotheses (mean 0, variance ``var0`` per axis). That prior is divided out (the
Gaussian quotient) so that it is not counted once per step::

    1 / var_lik = 1 / var - 1 / var0,    v_lik = v var_lik / var,    var_v = var_lik

Where the BOF knows nothing about the motion (``var >= var0``: no temporal filter, a new blob) or
``var_lik > velocity_max_std_m_s^2``, the cluster is a *position* measurement only (``H`` = the first two
rows of ``I_4``); a blob holding two people moving apart (a spread of velocities) weighs little.

Temporally correlated velocities. The BOF's velocity law in a cell is the product of every frame of evidence over
its memory, ``tau_v = 1 / velocity_noise_rate_hz`` (the rate at which its mass changes velocity hypothesis): two
clusters of the same person ``dt`` apart carry, for ``dt < tau_v``, mostly the same evidence about the motion.
Fused as independent measurements at every step, that evidence was counted ``tau_v / dt`` times: the track's
velocity became as certain as the BOF's and as late, carried on at a stop or a turn (the BOF's velocity lags the
person's by up to its memory) onto the next person or past the person's new position, an identity switch. In the Kalman
update (step 4) the velocity block of ``R`` is therefore scaled, as the pipeline weights a camera's frames
(:mod:`planefuse.tracking._async`)::

    R_vv <- R_vv max(1, tau_v / dt)

i.e. one whole velocity measurement per ``tau_v`` enters a track's state. Association (steps 3, 7) weighs each
step's hypotheses once, against each other, and accumulates nothing: it takes ``R`` (the cluster's velocity still
tells two people crossing apart), as does a new track (step 8: its first and only velocity so far).

Each step (``dt`` since the last one):

1. predict (filterpy ``predict``)::

       F = [[I, dt I], [0, I]],   x <- F x,   P <- F P F^T + Q,

   ``Q`` the discrete white-noise acceleration of standard deviation ``acceleration_std_m_s2``
   (filterpy ``Q_discrete_white_noise``);
2. gate: the position innovation ``y = z_p - x_p`` with ``S_p = P_pp + R_pp`` is admissible if
   ``y^T S_p^-1 y <= gate_chi2`` (chi-square, 2 d.o.f.) and ``|y| <= gate_m`` [m] (a hard cap for
   coasting tracks whose covariance has grown);
3. associate (global nearest neighbour on likelihood ratios): ``scipy.optimize.linear_sum_assignment`` on
   ``c_td = -2 ln LR_td``, the likelihood ratio of "cluster ``d`` is track ``t``'s person" against "track ``t``
   has no cluster this step and ``d`` is a false cluster" (a ghost, clutter of density ``lambda`` per m^2)::

       c_td = [y_p^T S_p^-1 y_p + ln det(2 pi S_p)] + [nll(v | p) - nll_c(v)] - 2 ln(P_D / ((1 - P_D) lambda))

   ``y_p``, ``S_p``: the position innovation and its covariance (``S = H P H^T + R``); where the cluster's
   velocity is informative, ``nll(v | p) = nll(y; S) - nll(y_p; S_p)`` is the velocity's conditional negative
   log-likelihood (two people crossing at one spot are told apart by their velocities), against
   ``nll_c(v) = |v|^2 / var_c + ln det(2 pi var_c I)``, the velocity of a false cluster drawn from the BOF's
   prior (``var_c = velocity_prior_var_m2_s2``, or ``initial_velocity_std_m_s^2`` without one).
   ``P_D = detection_probability``, ``lambda = clutter_density_per_m2``. Pairs outside the gate are
   forbidden, and each track may stay unassigned at cost 0 (a dummy column of its own), so that a pair is
   formed only where it is more likely than a miss plus a ghost. Without that option (the previous
   assignment) the number of matches was maximised first: a track was pulled onto a ghost 0.5 m away so
   that another track, coasting or held by weak evidence with a wide covariance, could take its cluster, an
   identity switch; the ``ln det`` term makes a wide (coasting) track a worse explanation than a tight one
   at the same Mahalanobis distance. Confirmed tracks are served first, tentative ones get the remaining
   clusters;
4. update every matched track (filterpy ``update``, Joseph form) with its cluster (velocity block of ``R``
   scaled by ``max(1, tau_v / dt)``, above); height and confidence are copied from it;
5. merged people: a confirmed track left without a cluster whose position gate holds a cluster taken by
   another confirmed track moving differently (velocities at least ``share_min_relative_speed_m_s``
   apart: people crossing, not a duplicate of the owner) *shares* it for at most ``max_shared_s`` in a
   row: both are updated with its position only, with the extra variance ``merged_position_std_m^2``
   (the blob's centre lies between the two people), so each keeps its own velocity through the merge. A merge
   begins only for a track that had evidence of its own (a cluster, support or a share) at the previous step: a
   track already lost, its covariance grown, would be dragged onto whoever walks by (a person standing unseen,
   pulled onto a passer-by, then switched with them). With appearance in association, a track does not share a
   blob whose colours are farther than ``appearance_update_max_distance`` from its model: its person has left the
   blob (the track is lost, and step 7 may find the person again);
6. support through weak evidence (applied before 5): a confirmed track still without a cluster looks at the
   column evidence ``S`` (:attr:`Clusters.column_log_odds`) within ``gate_m`` of its prediction, away (more than
   ``birth_exclusion_m``) from every cluster taken by another track. Where the filter still holds a person
   there below the clusters' threshold (partly hidden by an occluder, a camera gone: fewer views, weaker
   evidence), ``max S >= support_threshold``, the track is updated with that mode's position, the
   ``S``-weighted mean ``sum_c w_c p_c / sum_c w_c``, ``w_c = max(S_c, 0)``, over the cells ``c`` within
   ``person_radius_m`` of the strongest cell, as a position measurement of covariance
   ``(position_std_m^2 + merged_position_std_m^2) I``. Such a step is *supported*: the track is reported
   and its miss count reset, for at most ``max_supported_s`` since its last cluster (then it coasts);
7. re-acquisition: a confirmed track lost (no cluster, no support) for ``k >= 1`` steps, whose prediction ran
   on at constant velocity while its person stopped or turned unseen (fewer views during a camera dropout, the
   filter's evidence too weak), may take a cluster no track took inside its position gate, with the distance cap
   widened to ``gate_m + reacquire_speed_m_s (k + 1) dt``; every gated pair is formed (the alternative is a new
   track on the same cluster, not a ghost), globally by the costs of step 3. The track becomes *tentative*
   again, as a track born on that cluster would be (reported after ``confirm_hits`` hits in a row, ended at its
   first miss: a ghost it took dies as a ghost's track would), but keeps its id;
8. new tracks: an unmatched cluster farther than ``birth_exclusion_m`` from every confirmed track starts
   a tentative track at ``x = z``, ``P = R`` (velocity 0 where the cluster's is not informative; the
   velocity variance capped at ``initial_velocity_std_m_s^2``).

9. re-identification (with ``reid_max_s``): a track confirmed for the first time at this step takes the identity of
   a *lost* track (a confirmed track ended less than ``reid_max_s`` ago, or one still kept but without a cluster
   now) last seen within ``reid_max_distance_m`` of it whose appearance model is the nearest to its own, within
   ``reid_max_appearance_distance``; the lost track ends. The new track's first ``confirm_hits`` views make its
   model (a cluster that is a ghost seldom lives that long). With re-identification, step 7 refuses a lost track a
   cluster whose appearance is known and farther than ``reid_max_appearance_distance`` from its model.

Appearance
----------
With ``appearance_weight`` (or ``reid_max_s``) and an ``observer`` (:class:`planefuse.tracking.AppearanceObserver`,
which :class:`planefuse.pipeline.SystemRun` attaches), each step's clusters have a colour descriptor from every
camera that sees them, views hidden by a nearer person or by ignore regions left out
(:mod:`planefuse.tracking._appearance`). Every track keeps a model per camera, updated from the cluster it took
(not from a merged blob, step 5, nor from support, step 6) at ``appearance_update_rate``. The association cost of
step 3 (and 7) gets the appearance term, an approximate ``-2 ln`` likelihood ratio of "same person" against
"another person or a ghost" for the appearance distance ``d`` in [0, 1]::

    c_td += w (d_td - d0)          (w = appearance_weight, d0 = appearance_reference_distance)

0 where the distance is unknown (no camera where both the track's model and the cluster's view exist). Without
``appearance_weight`` and ``reid_max_s`` (the default) nothing of this runs: the tracker's decisions and state are
those without appearance.

Track management (states of a track)
------------------------------------
* **tentative**: born from an unexplained cluster; becomes *confirmed* after ``confirm_hits``
  consecutive hits, deleted at its first miss;
* **confirmed**: associated at this step (or sharing a merged cluster); reported;
* **supported**: confirmed, without a cluster but held by the filter's weaker evidence (step 6); reported;
* **coasting**: confirmed, without a cluster (or support) for ``misses`` consecutive steps: it moves on its
  prediction and ``P`` grows; reported while ``misses <= max_coast_report``, with confidence
  ``last cluster confidence x 0.5^misses``;
* **re-acquired**: a lost confirmed track that took a free cluster (step 7): tentative again, same id;
* **deleted**: a coasting track with ``misses > max_misses``, or whose prediction leaves the grid.

Step counts are in output steps (scale them with the output rate).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import predict as kf_predict
from filterpy.kalman import update as kf_update
from scipy.optimize import linear_sum_assignment

from .._params import check_fields
from .._state import StateDict, float_or_none, get, optional_float
from ._appearance import TrackAppearance, ViewDescriptors
from ._split import TrackViews
from ._bof import BOFParams, velocity_grid_m_s
from ._clustering import Clusters

__all__ = ["MultiPersonTracker", "TrackerParams", "Tracks", "cluster_measurements", "velocity_correlation_time_s",
           "velocity_prior_variance_m2_s2"]

_H_POS = np.eye(2, 4)  # position rows of the state


@dataclass(frozen=True)
class TrackerParams:
    """Parameters of :class:`MultiPersonTracker` (see the module docstring).

    Attributes
    ----------
    gate_m : float
        Largest distance [m] between a track's predicted position and its cluster.
    gate_chi2 : float
        Mahalanobis gate on the position innovation (chi-square, 2 degrees of freedom; 9.21 = 99 %).
    confirm_hits : int
        Consecutive hits that confirm a tentative track.
    max_misses : int
        Consecutive misses after which a confirmed track is deleted.
    max_coast_report : int
        Confirmed tracks with more consecutive misses than this are not reported (still kept).
    position_std_m : float
        ``s_p``: standard deviation [m] of a cluster's position, per axis.
    velocity_std_m_s : float
        ``s_v``: standard deviation [m/s] of a cluster's BOF velocity, per axis, added to its own variance.
    acceleration_std_m_s2 : float
        Standard deviation [m/s^2] of the white-noise acceleration of the constant-velocity model.
    velocity_max_std_m_s : float
        A cluster velocity whose likelihood standard deviation [m/s] exceeds this carries no motion
        information (e.g. without temporal filtering): the cluster is a position measurement only.
    initial_velocity_std_m_s : float
        Largest initial velocity standard deviation [m/s] of a new track.
    merged_position_std_m : float
        Extra position standard deviation [m] of a cluster shared by two tracks (merged people).
    max_shared_s : float
        Longest time [s] a track may share another track's cluster (people merged while crossing).
    share_min_relative_speed_m_s : float
        Tracks share a cluster only if their velocities differ by at least this [m/s] (people crossing;
        a track moving with the cluster's owner is a duplicate and is left to die).
    birth_exclusion_m : float
        No track is started on a cluster closer than this [m] to a confirmed track.
    detection_probability : float
        ``P_D``: probability that a person tracked gives a cluster at a step, in (0, 1) (association, step 3).
    clutter_density_per_m2 : float
        ``lambda``: density [1/m^2] of false clusters (multi-view ghosts, trails) per step (association, step
        3); only ``P_D / ((1 - P_D) lambda)`` matters.
    support_threshold : float or None
        Column evidence ``S`` (mean capped log-odds per observed body plane, as the clusters' threshold) that
        supports a confirmed track without a cluster (step 6); None: no support.
    person_radius_m : float
        Radius [m] of the disc whose column evidence gives a supported track's position.
    max_supported_s : float
        Longest time [s] a track is supported since its last cluster.
    velocity_decorrelation : bool
        Scale the clusters' velocity covariance by ``max(1, tau_v / dt)`` in the Kalman update (module docstring,
        "Temporally correlated velocities") where the caller gives ``tau_v`` (the pipeline: the BOF's velocity
        memory); False: every step's cluster velocity is an independent measurement. On (chosen on simulated seeds
        1-3); off for the EPFL terrace (chosen on its frames 0-1499, ``scripts/terrace.yaml``).
    reacquire_speed_m_s : float or None
        Re-acquisition (step 7): a confirmed track lost for ``k >= 1`` steps may take a cluster no track took
        within its covariance gate and ``gate_m + reacquire_speed_m_s x (k + 1) dt`` [m] of its prediction (a
        person who stopped or turned while unseen); None: never.
    appearance_weight : float or None
        Appearance in association ("Appearance" in the module docstring): ``w``, the pairing cost's change
        (``-2 ln LR`` units) per unit of appearance distance; None: association on position and velocity alone.
    appearance_reference_distance : float
        ``d0``: the appearance distance in [0, 1] at which a pairing is as likely as not to be the same person.
    appearance_update_rate : float
        Rate in (0, 1] at which a track's appearance model takes in each new view (after the first
        ``1 / rate`` views, averaged): a passer-by seen once moves it by at most this much.
    appearance_update_max_distance : float
        A view farther than this appearance distance from a track's model is not taken into it.
    reid_max_s : float or None
        Re-identification (step 9): a track lost for at most this long [s] is a candidate for a new track's
        identity; None: no re-identification.
    reid_max_distance_m : float
        Largest distance [m] between a lost track's last position and a new track's for re-identification.
    reid_max_appearance_distance : float
        Largest appearance distance between a lost track's model and a new track's for re-identification.
    """

    gate_m: float = 0.75
    gate_chi2: float = 9.21
    confirm_hits: int = 3
    max_misses: int = 10
    max_coast_report: int = 1  # with birth_exclusion_m: chosen on seeds 1-3 of every scenario (docs/results.md)
    position_std_m: float = 0.15  # with the acceleration noise: chosen on seeds 1-3 (docs/results.md)
    velocity_std_m_s: float = 0.3
    acceleration_std_m_s2: float = 2.0
    velocity_max_std_m_s: float = 2.0
    initial_velocity_std_m_s: float = 1.0
    merged_position_std_m: float = 0.25
    max_shared_s: float = 1.0
    share_min_relative_speed_m_s: float = 0.3
    birth_exclusion_m: float = 1.0  # chosen on seeds 1-3 of every scenario (docs/results.md)
    detection_probability: float = 0.9
    clutter_density_per_m2: float = 1.0  # chosen on seeds 1-3 of every scenario (docs/results.md)
    support_threshold: float | None = 1.0  # chosen on seeds 1-3 of every scenario (docs/results.md)
    person_radius_m: float = 0.3
    max_supported_s: float = 2.0
    reacquire_speed_m_s: float | None = 2.5  # chosen on seeds 1-3 (docs/results.md)
    velocity_decorrelation: bool = True  # chosen on seeds 1-3 (docs/results.md)
    appearance_weight: float | None = None
    appearance_reference_distance: float = 0.3
    appearance_update_rate: float = 0.1
    appearance_update_max_distance: float = 0.6
    reid_max_s: float | None = None
    reid_max_distance_m: float = 5.0
    reid_max_appearance_distance: float = 0.3

    @property
    def uses_appearance(self) -> bool:
        """Whether the tracks keep appearance models (association or re-identification use them)."""
        return self.appearance_weight is not None or self.reid_max_s is not None

    def __post_init__(self) -> None:
        check_fields(self, gate_m=">0", gate_chi2=">0", confirm_hits="int>=1", max_misses="int>=0",
                     max_coast_report="int>=0", position_std_m=">0", velocity_std_m_s=">0",
                     acceleration_std_m_s2=">=0", initial_velocity_std_m_s=">0",
                     velocity_max_std_m_s=">0", merged_position_std_m=">=0",
                     max_shared_s=">=0", share_min_relative_speed_m_s=">=0", birth_exclusion_m=">=0",
                     detection_probability="(0,1)", clutter_density_per_m2=">0",
                     support_threshold="?finite", person_radius_m=">0", max_supported_s=">=0",
                     reacquire_speed_m_s="?>=0", appearance_weight="?>=0",
                     appearance_reference_distance="[0,1]", appearance_update_rate="(0,1]",
                     appearance_update_max_distance="[0,1]", reid_max_s="?>=0", reid_max_distance_m=">=0",
                     reid_max_appearance_distance="[0,1]")


@dataclass(frozen=True)
class Tracks:
    """Reported tracks at one instant.

    Attributes
    ----------
    time_s : float
        Time [s].
    ids : ndarray, shape (N,), int64
        Track identities (unique over the tracker's life).
    xy_m : ndarray, shape (N, 2)
        Ground positions (world XY) [m].
    velocity_m_s : ndarray, shape (N, 2)
        Velocities (vx, vy) [m/s].
    height_m : ndarray, shape (N,)
        Heights [m] (NaN if unknown).
    confidence : ndarray, shape (N,)
        In [0, 1].
    misses : ndarray, shape (N,), int64
        Consecutive steps without a cluster (0 = observed now, > 0 = coasting on the prediction).
    """

    time_s: float
    ids: np.ndarray
    xy_m: np.ndarray
    velocity_m_s: np.ndarray
    height_m: np.ndarray
    confidence: np.ndarray
    misses: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


@dataclass
class _Track:
    id: int
    x: np.ndarray  # (4,) px, py [m], vx, vy [m/s]
    P: np.ndarray  # (4, 4)
    height: float
    confidence: float
    hits: int = 1
    misses: int = 0
    confirmed: bool = False
    shared_s: float = 0.0  # time [s] this track has been sharing another track's cluster in a row
    supported_s: float = 0.0  # time [s] this track has been supported by weak evidence since its last cluster
    app: TrackAppearance | None = None  # appearance per camera (with TrackerParams.uses_appearance)
    new: bool = True  # never confirmed yet (re-identification is tried once, when it is)
    last_seen_s: float = float("nan")  # time [s] of its last cluster
    last_xy: np.ndarray | None = None  # its position [m] after that update


def cluster_measurements(clusters: Clusters, params: TrackerParams, velocity_prior_var_m2_s2: float | None = None):
    """Measurements of every cluster (module docstring): ``z`` (N, 4) [m, m/s], ``R`` (N, 4, 4) and whether
    its velocity is informative, (N,) bool (where not, it is a position measurement only)."""
    n = len(clusters)
    z = np.concatenate([clusters.xy_m, clusters.velocity_m_s], axis=1).reshape(-1, 4)
    var = np.maximum(clusters.velocity_variance(), 1e-6)
    if velocity_prior_var_m2_s2 is None:
        lik_var = var
    else:  # divide the BOF's prior N(0, var0) out of its posterior N(v, var): the likelihood of the motion
        info = 1.0 / var - 1.0 / velocity_prior_var_m2_s2
        lik_var = np.full_like(var, np.inf)
        np.divide(1.0, info, out=lik_var, where=info > 0)
        z[:, 2:] = np.where(info > 0, z[:, 2:] / var * np.minimum(lik_var, 1e12), 0.0)
    lik_var = np.nan_to_num(lik_var, nan=np.inf)
    has_v = np.all(lik_var <= params.velocity_max_std_m_s**2, axis=1)
    R = np.zeros((n, 4, 4))
    R[:, [0, 1], [0, 1]] = params.position_std_m**2
    R[:, [2, 3], [2, 3]] = params.velocity_std_m_s**2 + np.where(has_v[:, None], lik_var, 0.0)
    z[~has_v, 2:] = 0.0
    return z, R, has_v


def velocity_correlation_time_s(bof: BOFParams) -> float:
    """Memory [s] of the BOF's velocity law, ``1 / velocity_noise_rate_hz`` (infinite without velocity noise): the
    time over which the velocities of its clusters carry the same evidence (module docstring)."""
    return 1.0 / bof.velocity_noise_rate_hz if bof.velocity_noise_rate_hz > 0 else float("inf")


def velocity_prior_variance_m2_s2(bof: BOFParams) -> float:
    """Variance [m^2/s^2] per axis of the BOF's uniform law over its velocity hypotheses, ``mean(v_k,x^2)``."""
    return float(np.mean(velocity_grid_m_s(bof)[:, 0] ** 2))


class MultiPersonTracker:
    """Track people from successive :class:`~planefuse.tracking.Clusters` (module docstring).

    Parameters
    ----------
    params : TrackerParams, optional
        Tracker parameters.
    extent_m : tuple of float, optional
        ``(x_min, x_max, y_min, y_max)`` [m]; a coasting track predicted outside is deleted.
    velocity_prior_var_m2_s2 : float, optional
        Prior variance [m^2/s^2] per axis of the velocity law behind the clusters' velocities (the BOF's
        uniform law over its hypotheses, :func:`velocity_prior_variance_m2_s2`), divided out of them; None:
        the cluster velocities are likelihoods already.
    velocity_correlation_s : float, optional
        ``tau_v`` [s]: the time over which the clusters' velocities carry the same evidence (the BOF's velocity
        memory, :func:`velocity_correlation_time_s`); their covariance is scaled by ``max(1, tau_v / dt)`` in the Kalman
        update (module docstring); infinite: the velocities never enter a track's state; None: independent from
        step to step.
    """

    def __init__(self, params: TrackerParams | None = None, extent_m=None,
                 velocity_prior_var_m2_s2: float | None = None, velocity_correlation_s: float | None = None) -> None:
        self.params = params if params is not None else TrackerParams()
        self.extent_m = extent_m
        self.velocity_prior_var_m2_s2 = velocity_prior_var_m2_s2
        if velocity_correlation_s is not None and not velocity_correlation_s > 0:
            raise ValueError(f"velocity_correlation_s must be > 0 s or None, got {velocity_correlation_s!r}")
        self.velocity_correlation_s = velocity_correlation_s
        self.tracks: list[_Track] = []
        self.time_s: float | None = None
        self._next_id = 1
        #: ``observer(time_s, xy_m (N, 2), occluders_xy_m (M, 2)) -> ViewDescriptors``: the appearance of a step's
        #: clusters (:class:`planefuse.tracking.AppearanceObserver`), asked where ``params.uses_appearance``
        self.observer = None
        #: every view a track takes, kept where the offline splitting asks for it (:class:`TrackViews`; None: not kept)
        self.view_log: TrackViews | None = None
        #: confirmed tracks ended less than ``reid_max_s`` ago: re-identification candidates (step 9)
        self.lost: list[_Track] = []
        #: each identity's latest appearance model (the outputs' summary, offline stitching)
        self.appearance_by_id: dict[int, TrackAppearance] = {}
        self._views: ViewDescriptors | None = None  # the current step's cluster appearance

    def _associate(self, group: list[_Track], z: np.ndarray, R: np.ndarray, has_v: np.ndarray, free: np.ndarray,
                   cap_m: np.ndarray | float | None = None, miss_cost: float = 0.0,
                   max_appearance_distance: float | None = None):
        """Gated optimal assignment of ``group`` to the still-free clusters: (track index, cluster index) pairs;
        ``cap_m`` (per track, or one value) [m]: the distance cap of the gate (default ``gate_m``); ``miss_cost``:
        the cost of leaving a track unassigned (0: a pair only where more likely than a miss and a ghost);
        ``max_appearance_distance``: pairs whose appearance distance is known and larger are forbidden."""
        det = np.flatnonzero(free)
        if not group or det.size == 0:
            return []
        x = np.array([tr.x for tr in group])
        P = np.array([tr.P for tr in group])
        y = z[det][None, :, :] - x[:, None, :]  # innovations, (T, D, 4)
        S = P[:, None] + R[det][None]  # (T, D, 4, 4)
        S_pos = S[..., :2, :2]
        d2_pos = np.einsum("tdi,tdij,tdj->td", y[..., :2], np.linalg.inv(S_pos), y[..., :2])
        p = self.params
        cap = np.broadcast_to(p.gate_m if cap_m is None else cap_m, (len(group),))
        gated = (d2_pos <= p.gate_chi2) & (np.linalg.norm(y[..., :2], axis=-1) <= cap[:, None])
        nll_pos = d2_pos + np.linalg.slogdet(2 * np.pi * S_pos)[1]
        nll_full = np.einsum("tdi,tdij,tdj->td", y, np.linalg.inv(S), y) + np.linalg.slogdet(2 * np.pi * S)[1]
        var_c = self.velocity_prior_var_m2_s2 or p.initial_velocity_std_m_s**2  # a false cluster's velocity law
        nll_c = np.sum(z[det, 2:] ** 2, axis=1) / var_c + 2 * np.log(2 * np.pi * var_c)
        cost = (nll_pos + np.where(has_v[det][None], nll_full - nll_pos - nll_c[None], 0.0)
                - 2 * np.log(p.detection_probability / ((1 - p.detection_probability) * p.clutter_density_per_m2)))
        if p.appearance_weight is not None and self._views is not None:
            cost = cost + self._appearance_cost(group, det)
        if max_appearance_distance is not None and self._views is not None:
            views = ViewDescriptors(self._views.hist[det], self._views.valid[det])
            for i, tr in enumerate(group):
                if tr.app is not None:
                    gated[i] &= ~(tr.app.distance(views) > max_appearance_distance)  # NaN (unknown) stays
        n_trk, n_det = cost.shape
        cost = np.concatenate([np.where(gated, cost, np.inf), np.full((n_trk, n_trk), np.inf)], axis=1)
        cost[np.arange(n_trk), n_det + np.arange(n_trk)] = miss_cost  # each track's own "no cluster this step"
        rows, cols = linear_sum_assignment(cost)
        return [(r, int(det[c])) for r, c in zip(rows, cols) if c < n_det]

    def _not_its_person(self, tr: _Track, ci: int) -> bool:
        """Whether cluster ``ci``'s views are farther than ``appearance_update_max_distance`` from ``tr``'s model
        (known to be someone else; False where unknown or without appearance in association)."""
        if self.params.appearance_weight is None or self._views is None or tr.app is None:
            return False
        d = tr.app.distance(ViewDescriptors(self._views.hist[ci:ci + 1], self._views.valid[ci:ci + 1]))[0]
        return bool(d > self.params.appearance_update_max_distance)

    def _appearance_cost(self, group: list[_Track], det: np.ndarray) -> np.ndarray:
        """``w (d - d0)`` (T, D) per track and free cluster, ``d`` their appearance distance; 0 where unknown."""
        p = self.params
        views = ViewDescriptors(self._views.hist[det], self._views.valid[det])
        out = np.zeros((len(group), len(det)))
        for i, tr in enumerate(group):
            if tr.app is not None:
                d = tr.app.distance(views)
                out[i] = np.where(np.isfinite(d), p.appearance_weight * (d - p.appearance_reference_distance), 0.0)
        return out

    def predicted_xy(self, time_s: float) -> np.ndarray:
        """Positions (N, 2) [m, world] of the confirmed tracks moved at their velocities from the tracker's time
        to ``time_s`` [s] (the state is not changed); (0, 2) before the first step."""
        if self.time_s is None:
            return np.zeros((0, 2))
        dt = float(time_s) - self.time_s
        return np.array([tr.x[:2] + tr.x[2:] * dt for tr in self.tracks if tr.confirmed]).reshape(-1, 2)

    def step(self, clusters: Clusters) -> Tracks:
        """Advance to ``clusters.time_s``, associate and update; return the reported tracks."""
        p = self.params
        t = float(clusters.time_s)
        dt = 0.0 if self.time_s is None else t - self.time_s
        if dt < 0:
            raise ValueError(f"clusters.time_s {t} is before the tracker time {self.time_s}")
        self.time_s = t
        if self.tracks and dt > 0:
            F = np.eye(4)
            F[0, 2] = F[1, 3] = dt
            Q = Q_discrete_white_noise(2, dt, p.acceleration_std_m_s2**2, block_size=2, order_by_dim=False)
            for tr in self.tracks:
                tr.x, tr.P = kf_predict(tr.x, tr.P, F, Q)
        z, R, has_v = cluster_measurements(clusters, p, self.velocity_prior_var_m2_s2)
        self._views = self._observe(clusters) if p.uses_appearance else None
        R_upd, has_v_upd = self._decorrelate(R, has_v, dt)  # what an update takes in; association and birth take R
        free = np.ones(len(clusters), bool)
        owner: dict[int, _Track] = {}  # cluster index -> confirmed track that took it
        matched: set[int] = set()
        for group in ([tr for tr in self.tracks if tr.confirmed], [tr for tr in self.tracks if not tr.confirmed]):
            for ti, ci in self._associate(group, z, R, has_v, free):
                tr = group[ti]
                free[ci] = False
                matched.add(tr.id)
                if tr.confirmed:
                    owner[ci] = tr
                else:
                    self._update(tr, z[ci], R_upd[ci], clusters, ci, position_only=not has_v_upd[ci])
        taken = z[~free, :2]
        for tr in self.tracks:  # step 6 before 5: a mode of its own is better evidence than a shared blob
            if tr.id in matched:
                tr.supported_s = 0.0
            elif tr.confirmed and self._support(tr, clusters, taken, dt):
                matched.add(tr.id)
        sharers = self._sharers(owner, matched, z, R, dt)
        for ci, tr in owner.items():
            # a merged blob: its position only, for the owner and its sharers alike
            self._update(tr, z[ci], R_upd[ci], clusters, ci, position_only=ci in sharers or not has_v_upd[ci],
                         merged=ci in sharers)
            for sharer in sharers.get(ci, ()):
                self._update_shared(sharer, z[ci, :2], R[ci, :2, :2], dt)
                matched.add(sharer.id)
        self._reacquire(matched, z, R, has_v, free, clusters, dt)
        alive = []
        for tr in self.tracks:
            if tr.id not in matched:
                tr.misses += 1
                if not tr.confirmed or tr.misses > p.max_misses or not self._inside(tr.x[:2]):
                    if p.reid_max_s is not None and not tr.new and tr.app is not None:
                        self.lost.append(tr)  # a re-identification candidate (step 9)
                    elif self.view_log is not None:  # ended for good: its views reduced to its cuts and pieces
                        self.view_log.finalize(tr.id)
                    continue
            alive.append(tr)
        if p.reid_max_s is not None:
            alive = self._reidentify(alive, t)
        confirmed_xy = np.array([tr.x[:2] for tr in alive if tr.confirmed]).reshape(-1, 2)
        for ci in np.flatnonzero(free):
            near = np.linalg.norm(confirmed_xy - z[ci, :2], axis=-1)
            if near.size and near.min() < p.birth_exclusion_m:
                continue  # a second mode of someone already tracked, not a new person
            P0 = R[ci].copy()
            v_var = R[ci, [2, 3], [2, 3]] if has_v[ci] else np.full(2, np.inf)  # unknown: the initial spread
            P0[[2, 3], [2, 3]] = np.minimum(v_var, p.initial_velocity_std_m_s**2)
            born = _Track(self._next_id, z[ci].copy(), P0, float(clusters.height_m[ci]),
                          float(clusters.confidence[ci]), confirmed=p.confirm_hits <= 1)
            if p.uses_appearance:
                born.app = TrackAppearance(np.zeros(self._views.hist.shape[1:]), np.zeros(self._views.hist.shape[1]))
                self._absorb(born, ci)
            alive.append(born)
            self._next_id += 1
        self.tracks = alive
        return self.reported()

    def _reacquire(self, matched: set[int], z: np.ndarray, R: np.ndarray, has_v: np.ndarray, free: np.ndarray,
                   clusters: Clusters, dt: float) -> None:
        """Step 7 (module docstring): confirmed tracks lost for at least one step take the clusters no track took,
        within their covariance gate and ``gate_m + reacquire_speed_m_s x`` the time since their last cluster."""
        p = self.params
        if p.reacquire_speed_m_s is None:
            return
        lost = [tr for tr in self.tracks if tr.confirmed and tr.id not in matched and tr.misses >= 1]
        cap = np.array([p.gate_m + p.reacquire_speed_m_s * (tr.misses + 1) * dt for tr in lost])
        # every gated pair is taken (the cost of a miss above any pair's): the alternative to the lost person is a
        # new one, born on the same cluster, not a ghost
        # with re-identification, a lost track takes back no cluster whose appearance is not its person's
        max_d = p.reid_max_appearance_distance if p.reid_max_s is not None else None
        for ti, ci in self._associate(lost, z, R, has_v, free, cap, miss_cost=1e9, max_appearance_distance=max_d):
            tr = lost[ti]
            free[ci] = False
            matched.add(tr.id)
            tr.supported_s = 0.0
            # tentative again, as a track born on this cluster would be: reported after confirm_hits hits in a row,
            # ended at its first miss (a ghost it took), but under its own id
            tr.confirmed, tr.hits = False, 0
            self._update(tr, z[ci], R[ci], clusters, ci, position_only=True)

    def _decorrelate(self, R: np.ndarray, has_v: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The clusters' measurement covariances ``R`` (N, 4, 4) with the velocity block scaled by
        ``max(1, tau / dt)`` (module docstring, "Temporally correlated velocities"), and which velocities are
        informative, (N,) bool: none for an infinite ``tau`` (a filter that never forgets a velocity)."""
        tau = self.velocity_correlation_s
        if tau is None or not self.params.velocity_decorrelation or dt <= 0 or tau <= dt:
            return R, has_v
        if np.isinf(tau):
            return R, np.zeros_like(has_v)
        out = R.copy()
        out[:, 2:, 2:] *= tau / dt
        return out, has_v

    def _update(self, tr: _Track, z: np.ndarray, R: np.ndarray, clusters: Clusters, ci: int,
                position_only: bool = False, merged: bool = False) -> None:
        """Kalman update of a track that took cluster ``ci`` (a hit); ``merged``: the cluster is shared."""
        if position_only:
            self._update_position(tr, z[:2], R[:2, :2], merged)
        else:
            tr.x, tr.P = kf_update(tr.x, tr.P, z, R, np.eye(4))
        if not merged:
            tr.shared_s = 0.0
        if np.isfinite(clusters.height_m[ci]):
            tr.height = float(clusters.height_m[ci])
        tr.confidence = float(clusters.confidence[ci])
        tr.hits += 1
        tr.misses = 0
        tr.confirmed = tr.confirmed or tr.hits >= self.params.confirm_hits
        if self._views is not None and not merged:  # a merged blob's views hold two people
            self._absorb(tr, ci)

    def _absorb(self, tr: _Track, ci: int) -> None:
        """Take cluster ``ci``'s views into ``tr``'s appearance model; note when and where it was last seen."""
        p = self.params
        if tr.app is None:
            tr.app = TrackAppearance(np.zeros(self._views.hist.shape[1:]), np.zeros(self._views.hist.shape[1]))
        tr.app.update(self._views, ci, p.appearance_update_rate, p.appearance_update_max_distance)
        if self.view_log is not None and self._views.valid[ci].any():
            self.view_log.add(self.time_s, tr.id, self._views, ci)
        tr.last_seen_s, tr.last_xy = float(self.time_s), tr.x[:2].copy()
        if tr.confirmed:
            self.appearance_by_id[tr.id] = tr.app

    def _observe(self, clusters: Clusters) -> ViewDescriptors | None:
        """The appearance of the step's clusters (``observer``), with the confirmed tracks predicted more than a
        person's width from every cluster as further occluders (people hidden now, but standing there)."""
        if self.observer is None:
            return None
        xy = np.asarray(clusters.xy_m, float).reshape(-1, 2)
        pred = np.array([tr.x[:2] for tr in self.tracks if tr.confirmed]).reshape(-1, 2)
        if len(xy) and len(pred):
            pred = pred[np.min(np.linalg.norm(pred[:, None] - xy[None], axis=-1), axis=1) > 0.6]
        return self.observer(float(clusters.time_s), xy, pred)

    def _reidentify(self, alive: list[_Track], t: float) -> list[_Track]:
        """Step 9: a track confirmed at this step for the first time takes the identity of the lost track (ended, or
        confirmed and without a cluster now) last seen within ``reid_max_s`` and ``reid_max_distance_m`` whose
        appearance is nearest its own, within ``reid_max_appearance_distance``; the lost track ends."""
        p = self.params
        for tr in self.lost:
            if t - tr.last_seen_s > p.reid_max_s and self.view_log is not None:
                self.view_log.finalize(tr.id)  # no re-identification can revive it now
        self.lost = [tr for tr in self.lost if t - tr.last_seen_s <= p.reid_max_s]
        for tr in [tr for tr in alive if tr.confirmed and tr.new]:
            tr.new = False
            if tr.app is None or not tr.app.count.any():
                continue
            cands = [c for c in self.lost + [a for a in alive if a.confirmed and not a.new and a.misses >= 1]
                     if c.app is not None and c.last_xy is not None and t - c.last_seen_s <= p.reid_max_s
                     and np.linalg.norm(tr.x[:2] - c.last_xy) <= p.reid_max_distance_m]
            best, best_d = None, p.reid_max_appearance_distance
            for c in cands:
                d = tr.app.distance_to(c.app)
                if np.isfinite(d) and d <= best_d:
                    best, best_d = c, d
            if best is None:
                continue
            self.appearance_by_id.pop(tr.id, None)
            if self.view_log is not None:
                self.view_log.finalize(tr.id)  # its first views keep their own (never reported) identity
            tr.id, tr.app = best.id, best.app.merged(tr.app)
            self.appearance_by_id[tr.id] = tr.app
            if best in self.lost:
                self.lost.remove(best)
            else:
                alive = [a for a in alive if a is not best]
        return alive

    def _sharers(self, owner: dict[int, _Track], matched: set[int], z: np.ndarray, R: np.ndarray,
                 dt: float) -> dict[int, list[_Track]]:
        """Confirmed tracks left without a cluster that share an owned cluster (merged people, step 5)."""
        p = self.params
        out: dict[int, list[_Track]] = {}
        if not owner:
            return out
        cis = np.array(list(owner))
        for tr in self.tracks:
            # a merge begins where the track still had evidence of its own at the previous step: a track already
            # lost, whose covariance has grown, would be pulled onto whoever walks by
            if not tr.confirmed or tr.id in matched or tr.misses > 0 or tr.shared_s + dt > p.max_shared_s:
                continue
            y = z[cis, :2] - tr.x[:2]
            S = tr.P[:2, :2] + R[cis, :2, :2] + p.merged_position_std_m**2 * np.eye(2)
            d2 = np.einsum("di,dij,dj->d", y, np.linalg.inv(S), y)
            ok = (d2 <= p.gate_chi2) & (np.linalg.norm(y, axis=-1) <= p.gate_m)
            if not ok.any():
                continue
            k = int(np.argmin(np.where(ok, d2, np.inf)))
            if np.linalg.norm(tr.x[2:] - owner[int(cis[k])].x[2:]) < p.share_min_relative_speed_m_s:
                continue  # moving with the owner: a duplicate of the same person, not a crossing
            if self._not_its_person(tr, int(cis[k])):
                continue  # the blob's colours are someone else's: the person has left it (lost, step 7 may find it)
            out.setdefault(int(cis[k]), []).append(tr)
        return out

    def _update_shared(self, tr: _Track, z_xy: np.ndarray, R_xy: np.ndarray, dt: float) -> None:
        """A sharer's update: the merged cluster's position only, with the extra merged variance; no hit."""
        self._update_position(tr, z_xy, R_xy, merged=True)
        tr.shared_s += dt
        tr.misses = 0

    def _update_position(self, tr: _Track, z_xy: np.ndarray, R_xy: np.ndarray, merged: bool) -> None:
        """Kalman update with a cluster's position only; a merged cluster's centre lies between its people
        (extra variance ``merged_position_std_m^2``)."""
        R_pos = R_xy + self.params.merged_position_std_m**2 * np.eye(2) if merged else R_xy
        tr.x, tr.P = kf_update(tr.x, tr.P, z_xy, R_pos, _H_POS)

    def _support(self, tr: _Track, clusters: Clusters, taken_xy: np.ndarray, dt: float) -> bool:
        """Step 6: update ``tr`` with the mode of the column evidence near its prediction, if strong enough;
        True if it was supported."""
        p = self.params
        S = clusters.column_log_odds
        if (p.support_threshold is None or self.extent_m is None or S is None or not np.size(S)
                or tr.supported_s + dt > p.max_supported_s):
            return False
        x0, x1, y0, y1 = self.extent_m
        ny, nx = S.shape
        cell = (x1 - x0) / nx
        # the cells within gate_m of the prediction (a window around it, then the disc)
        cx, cy = (tr.x[0] - x0) / cell - 0.5, (tr.x[1] - y0) / cell - 0.5
        r = int(np.ceil(p.gate_m / cell))
        ix = np.arange(max(int(cx) - r, 0), min(int(cx) + r + 2, nx))
        iy = np.arange(max(int(cy) - r, 0), min(int(cy) + r + 2, ny))
        if not ix.size or not iy.size:
            return False
        X, Y = np.meshgrid(x0 + (ix + 0.5) * cell, y0 + (iy + 0.5) * cell)
        win = S[np.ix_(iy, ix)]
        ok = np.hypot(X - tr.x[0], Y - tr.x[1]) <= p.gate_m
        for q in taken_xy:  # another track's person: not this one's
            ok &= np.hypot(X - q[0], Y - q[1]) > p.birth_exclusion_m
        if not ok.any():
            return False
        k = np.unravel_index(np.argmax(np.where(ok, win, -np.inf)), win.shape)
        if not win[k] >= p.support_threshold:
            return False
        disc = ok & (np.hypot(X - X[k], Y - Y[k]) <= p.person_radius_m)
        w = np.where(disc, np.maximum(win, 0.0), 0.0)
        z_xy = np.array([np.sum(w * X), np.sum(w * Y)]) / np.sum(w)
        self._update_position(tr, z_xy, p.position_std_m**2 * np.eye(2), merged=True)
        tr.supported_s += dt
        tr.misses = 0
        return True

    def _inside(self, xy: np.ndarray) -> bool:
        if self.extent_m is None:
            return True
        x0, x1, y0, y1 = self.extent_m
        return bool(x0 <= xy[0] <= x1 and y0 <= xy[1] <= y1)

    # -- checkpoint ------------------------------------------------------------------------------------------------
    _TRACK_FIELDS = ("id", "x", "P", "height", "confidence", "hits", "misses", "confirmed", "shared_s",
                     "supported_s")

    def state_dict(self) -> StateDict:
        """Every track (tentative ones included: state ``x`` (N, 4), covariance ``P`` (N, 4, 4) and the
        management counters), the clock and the next identity, as arrays; with appearance, every track's and lost
        track's appearance model too."""
        tr = self.tracks
        extra = self._appearance_state() if self.params.uses_appearance else {}
        return {**extra,
            "time_s": optional_float(self.time_s),
            "next_id": np.asarray(self._next_id, dtype=np.int64),
            "id": np.array([t.id for t in tr], dtype=np.int64),
            "x": np.array([t.x for t in tr], dtype=float).reshape(-1, 4),
            "P": np.array([t.P for t in tr], dtype=float).reshape(-1, 4, 4),
            "height": np.array([t.height for t in tr], dtype=float),
            "confidence": np.array([t.confidence for t in tr], dtype=float),
            "hits": np.array([t.hits for t in tr], dtype=np.int64),
            "misses": np.array([t.misses for t in tr], dtype=np.int64),
            "confirmed": np.array([t.confirmed for t in tr], dtype=bool),
            "shared_s": np.array([t.shared_s for t in tr], dtype=float),
            "supported_s": np.array([t.supported_s for t in tr], dtype=float),
        }

    def _appearance_state(self) -> StateDict:
        every = self.tracks + self.lost
        n_c = next((t.app.count.size for t in every if t.app is not None), 0)
        shape = next((t.app.hist.shape for t in every if t.app is not None), (0, 2, 0))
        ids = sorted(self.appearance_by_id)
        return {
            "app_hist": np.array([t.app.hist if t.app is not None else np.zeros(shape) for t in every]
                                 ).reshape((-1,) + shape),
            "app_count": np.array([t.app.count if t.app is not None else np.full(n_c, -1.0) for t in every]
                                  ).reshape(-1, n_c),
            "app_new": np.array([t.new for t in every], dtype=bool),
            "app_last_seen_s": np.array([t.last_seen_s for t in every], dtype=float),
            "app_last_xy": np.array([t.last_xy if t.last_xy is not None else (np.nan, np.nan) for t in every],
                                    dtype=float).reshape(-1, 2),
            "lost_id": np.array([t.id for t in self.lost], dtype=np.int64),
            "lost_x": np.array([t.x for t in self.lost], dtype=float).reshape(-1, 4),
            "by_id": np.array(ids, dtype=np.int64),
            "by_id_hist": np.array([self.appearance_by_id[i].hist for i in ids]).reshape((-1,) + shape),
            "by_id_count": np.array([self.appearance_by_id[i].count for i in ids]).reshape(-1, n_c),
        }

    def _load_appearance_state(self, state) -> None:
        hist, count = get(state, "app_hist", "tracker"), get(state, "app_count", "tracker")
        new, seen, last = (get(state, k, "tracker") for k in ("app_new", "app_last_seen_s", "app_last_xy"))
        lost_id, lost_x = get(state, "lost_id", "tracker"), get(state, "lost_x", "tracker")
        self.lost = [_Track(int(i), np.array(x, dtype=float), np.eye(4), float("nan"), 0.0, confirmed=False)
                     for i, x in zip(lost_id, lost_x)]
        for k, t in enumerate(self.tracks + self.lost):
            t.app = TrackAppearance(np.array(hist[k]), np.array(count[k])) if np.all(count[k] >= 0) else None
            t.new, t.last_seen_s = bool(new[k]), float(seen[k])
            t.last_xy = None if np.isnan(last[k]).any() else np.array(last[k], dtype=float)
        self.appearance_by_id = {int(i): TrackAppearance(np.array(h), np.array(c)) for i, h, c in zip(
            get(state, "by_id", "tracker"), get(state, "by_id_hist", "tracker"), get(state, "by_id_count", "tracker"))}

    def appearance_summary(self, params, camera_names=None) -> dict[int, str]:
        """Per identity ever confirmed, its latest appearance model in words (:meth:`TrackAppearance.summary` with
        the :class:`AppearanceParams` ``params``)."""
        return {i: a.summary(params, camera_names) for i, a in sorted(self.appearance_by_id.items())}

    def load_state_dict(self, state) -> None:
        """Restore what :meth:`state_dict` saved."""
        cols = {k: get(state, k, "tracker") for k in self._TRACK_FIELDS}
        n = len(cols["id"])
        if any(len(c) != n for c in cols.values()):
            raise ValueError(f"tracker state: track fields disagree in length "
                             f"({ {k: len(c) for k, c in cols.items()} })")
        if np.shape(cols["x"])[1:] != (4,) or np.shape(cols["P"])[1:] != (4, 4):
            raise ValueError(f"tracker state: x must have shape (N, 4) and P (N, 4, 4), got "
                             f"{np.shape(cols['x'])} and {np.shape(cols['P'])}")
        self.tracks = [
            _Track(int(cols["id"][i]), np.array(cols["x"][i], dtype=float), np.array(cols["P"][i], dtype=float),
                   float(cols["height"][i]), float(cols["confidence"][i]), hits=int(cols["hits"][i]),
                   misses=int(cols["misses"][i]), confirmed=bool(cols["confirmed"][i]),
                   shared_s=float(cols["shared_s"][i]), supported_s=float(cols["supported_s"][i]))
            for i in range(n)
        ]
        self.time_s = float_or_none(get(state, "time_s", "tracker"))
        self._next_id = int(get(state, "next_id", "tracker"))
        if self.params.uses_appearance:
            self._load_appearance_state(state)

    def reported(self) -> Tracks:
        """Confirmed tracks with at most ``max_coast_report`` consecutive misses."""
        rep = [tr for tr in self.tracks if tr.confirmed and tr.misses <= self.params.max_coast_report]
        x = np.array([tr.x for tr in rep]).reshape(-1, 4)
        return Tracks(
            float(self.time_s) if self.time_s is not None else float("nan"),
            np.array([tr.id for tr in rep], dtype=np.int64),
            x[:, :2].copy(),
            x[:, 2:].copy(),
            np.array([tr.height for tr in rep], dtype=float),
            np.array([tr.confidence * 0.5**tr.misses for tr in rep], dtype=float),
            np.array([tr.misses for tr in rep], dtype=np.int64),
        )

