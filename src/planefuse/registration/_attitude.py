"""Cameras registered through their attitude over time: the seed's inertial route in the running system.

Each camera takes its attitude from one of two sources (:class:`RegistrationParams`):

* ``"calibration"``: the fixed ``T_world_cam`` of the calibration; its lookup is built once.
* ``"imu"``: roll and pitch from the camera's IMU (an :func:`~planefuse.geometry.attitude_from_imu` filter),
  the heading about gravity fixed once by :func:`~planefuse.geometry.yaw_from_ground_points` on ground points
  the calibrated camera sees at its first frame (the calibration's moment) and followed afterwards by the
  filter's gyroscope integration, the optical centre from the calibration. At that moment the calibration,
  measured on the images, is trusted over the IMU: what still separates the two attitudes (the IMU's
  mounting error on the camera and the accelerometer bias, ~0.1-0.5 deg for the simulator's IMU, i.e. a few
  pixels) is kept as a fixed correction in the camera frame (``refine_mount``), so the IMU gives the
  camera's motion since calibration, not a second, slightly different rest attitude. Before that moment
  (the filter settling over the still start of the stream) the attitude is the one at it.

The camera turns about its optical centre, so a change of attitude ``R0 -> R`` moves an undistorted pixel
``u`` to ``pi(K R^T R0 K^-1 u)`` (the infinite homography, seed eq. H = K' R K^-1): the frames of a camera
that turned are mapped back to its calibrated view (:meth:`CameraRegistration.stabilise`, lens distortion
included), and the calibration's image -> plane lookup and the background model, learned in that view,
stay valid. The map follows the attitude: it is rebuilt when the attitude has turned far enough from the
one it was built for to move some image point by more than ``tolerance_px`` pixels (measured on a 3 x 3
grid of image points: corners, edge midpoints, centre) while the gyroscope sees the camera turn, and by
more than ``still_tolerance_px`` while it is still (the filter's wander), so a still camera costs nothing
and a moving one a ``cv2.remap`` per frame.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..geometry import (
    DEFAULT_ATTITUDE_FILTER,
    PinholeCamera,
    R_world_cam_from_attitude,
    distort_normalized,
    attitude_from_imu,
    yaw_from_ground_points,
)
from ..grid import PlaneStack, cells_hidden_by_occluders, check_occluder_boxes
from ._lookup import ImagePlaneLookup

__all__ = ["ATTITUDE_SOURCES", "AttitudeTrack", "CameraRegistration", "RegistrationParams",
           "ground_reprojection_error_m", "gyro_bias_at_rest", "pixel_shift_px", "rest_at_start_s"]

#: Where a camera's attitude comes from.
ATTITUDE_SOURCES = ("calibration", "imu")


@dataclass(frozen=True)
class RegistrationParams:
    """How cameras are registered on the planes.

    Attributes
    ----------
    attitude_source : {"calibration", "imu"}
        Default source of every camera's attitude.
    attitude_source_by_camera : mapping of str -> str
        Per-camera exceptions (camera name -> source).
    tolerance_px : float
        While the camera turns, its stabilising map is rebuilt when the attitude has moved some image point
        by more than this [px] since the map was built. 0.25 px: a 1 px lag on a swaying camera's textured
        background already shows as foreground (docs/results.md, "Cameras that move").
    still_tolerance_px : float
        While the gyroscope says the camera is still (mean rate over ``still_window_s`` below
        ``still_rate_rad_s``), the map is rebuilt only past this larger shift [px]: the filter's own wander
        on a still simulated camera stays below 0.7 px, so a still camera is never rebuilt; a slow drift
        still is, past 1 px. (A ``tolerance_px`` above it applies in both cases.)
    still_rate_rad_s : float
        Rate below which the camera counts as still [rad/s] (1 deg/s: ~20 x the noise of the 0.1 s mean of
        the simulated gyroscope; a 1.5 deg sway of 3 s peaks at 3 deg/s).
    still_window_s : float
        Window of the mean rate [s].
    refine_mount : bool
        Keep the difference between the calibration and the IMU attitude at the calibration's moment as a
        fixed camera-frame correction (see the module docstring); False: the filter's roll and pitch as is.
    imu_filter : str
        :func:`~planefuse.geometry.attitude_from_imu` method.
    imu_filter_params : mapping, optional
        Its parameters (None = the method's defaults).
    gyro_bias_rest_s : float
        The gyroscope bias is the mean rate over the still start of the IMU stream (until the rate first
        exceeds 2 deg/s, at most ``gyro_bias_rest_s`` seconds, at least 0.25 s); 0 disables the estimate.
        Without it the heading, which only the gyroscope sees, drifts by the bias (~0.2 deg/s for the
        simulator's IMU). The heading is anchored on the calibration at the end of that still start (the
        filter has settled; the camera has not moved since its first frame).
    """

    attitude_source: str = "calibration"
    attitude_source_by_camera: Mapping[str, str] = field(default_factory=dict)
    tolerance_px: float = 0.25
    still_tolerance_px: float = 1.0
    still_rate_rad_s: float = float(np.radians(1.0))
    still_window_s: float = 0.1
    refine_mount: bool = True
    imu_filter: str = DEFAULT_ATTITUDE_FILTER
    imu_filter_params: Mapping[str, float] | None = None
    gyro_bias_rest_s: float = 1.0

    def __post_init__(self) -> None:
        for name, src in [("attitude_source", self.attitude_source),
                          *((f"attitude_source_by_camera[{k!r}]", v) for k, v in self.attitude_source_by_camera.items())]:
            if src not in ATTITUDE_SOURCES:
                raise ValueError(f"{name} must be one of {ATTITUDE_SOURCES}, got {src!r}")
        if not self.tolerance_px > 0:
            raise ValueError(f"tolerance_px must be > 0, got {self.tolerance_px}")
        if not self.still_tolerance_px > 0:
            raise ValueError(f"still_tolerance_px must be > 0, got {self.still_tolerance_px}")
        if not self.gyro_bias_rest_s >= 0:
            raise ValueError(f"gyro_bias_rest_s must be >= 0, got {self.gyro_bias_rest_s}")

    def source_of(self, camera_name: str) -> str:
        """The attitude source of camera ``camera_name``."""
        return self.attitude_source_by_camera.get(camera_name, self.attitude_source)


def rest_at_start_s(time_s, gyro_rad_s, max_s: float, max_rate_rad_s: float = np.radians(2.0)) -> float:
    """How long the IMU is still at the start of its stream [s], at most ``max_s``: the time until the first
    sample whose rate exceeds ``max_rate_rad_s`` (2 deg/s by default: ten times the simulator's bias, below
    any deliberate motion)."""
    t = np.asarray(time_s, dtype=float)
    moving = np.flatnonzero(np.linalg.norm(np.asarray(gyro_rad_s, dtype=float), axis=1) > max_rate_rad_s)
    end = t[moving[0]] if moving.size else t[-1]
    return float(min(end - t[0], max_s))


def gyro_bias_at_rest(time_s, gyro_rad_s, rest_s: float, min_rest_s: float = 0.25) -> np.ndarray:
    """Mean gyroscope rate [rad/s] (3,) over the still start of the stream (:func:`rest_at_start_s`, at most
    ``rest_s``), or zeros when it is shorter than ``min_rest_s``."""
    t = np.asarray(time_s, dtype=float)
    still = rest_at_start_s(t, gyro_rad_s, rest_s)
    window = t < t[0] + still
    if rest_s <= 0 or still < min_rest_s or window.sum() < 2:
        return np.zeros(3)
    return np.asarray(gyro_rad_s, dtype=float)[window].mean(axis=0)


def pixel_shift_px(K, R_world_cam_a, R_world_cam_b, width_px: int, height_px: int) -> float:
    """Largest displacement [px] of a 3 x 3 grid of image points between two attitudes of a camera turning
    about its centre: ``max |pi(K R_b^T R_a K^-1 u) - u|``."""
    K = np.asarray(K, dtype=float)
    u, v = np.meshgrid([0.0, (width_px - 1) / 2, width_px - 1.0], [0.0, (height_px - 1) / 2, height_px - 1.0])
    uv1 = np.stack([u.ravel(), v.ravel(), np.ones(9)], axis=1)
    H = K @ np.asarray(R_world_cam_b).T @ np.asarray(R_world_cam_a) @ np.linalg.inv(K)
    q = uv1 @ H.T
    with np.errstate(divide="ignore", invalid="ignore"):
        shift = np.linalg.norm(q[:, :2] / q[:, 2:3] - uv1[:, :2], axis=1)
    return float(np.max(np.where(q[:, 2] > 0, shift, np.inf)))


def ground_reprojection_error_m(center_world, R_world_cam_true, R_world_cam_used, xy_world) -> np.ndarray:
    """How far a registration puts ground points (z = 0) that a camera sees: each point is projected into the
    image with the camera's true attitude, and its pixel taken back to the ground with the attitude the
    registration uses [m], (N,); NaN for points behind the true camera or whose pixel's ray misses the ground.

    The pixel's ray is the point's direction in the camera frame whatever the intrinsics and lens (the same
    on both sides), so only attitudes enter.

    Parameters
    ----------
    center_world : array_like, shape (3,)
        Optical centre [m], world frame.
    R_world_cam_true, R_world_cam_used : array_like, shape (3, 3)
        True attitude and the one the registration uses (camera -> world).
    xy_world : array_like, shape (N, 2)
        Ground points, world XY [m].
    """
    c = np.asarray(center_world, dtype=float)
    xy = np.asarray(xy_world, dtype=float).reshape(-1, 2)
    p = np.c_[xy, np.zeros(len(xy))]
    x_cam = (p - c) @ np.asarray(R_world_cam_true)  # rows: R^T (p - c)
    d = x_cam @ np.asarray(R_world_cam_used).T  # the same pixel's ray, turned by the used attitude
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -c[2] / d[:, 2]
        err = np.linalg.norm(c[:2] + s[:, None] * d[:, :2] - p[:, :2], axis=1)
    return np.where((x_cam[:, 2] > 0) & (d[:, 2] < 0), err, np.nan)


@dataclass(frozen=True)
class AttitudeTrack:
    """A camera's attitude in the world over time, from its IMU.

    Attributes
    ----------
    times_s : ndarray, shape (N,)
        IMU sample times [s].
    R_world_cam : ndarray, shape (N, 3, 3)
        Camera axes in the world at each sample.
    yaw_rad : float
        Heading offset from the filter's gravity frame to the world.
    gyro_bias_rad_s : ndarray, shape (3,)
        Gyroscope bias removed before filtering (IMU frame).
    R_mount : ndarray, shape (3, 3)
        Camera-frame correction: ``R_world_cam = Rz(yaw) R_gravity_cam R_mount`` (identity without
        ``refine_mount``).
    reference_time_s : float
        When the attitude was anchored on the calibration; earlier samples hold the attitude there.
    rate_rad_s : ndarray, shape (N,), optional
        Mean bias-corrected gyroscope rate magnitude over the window ending at each sample [rad/s].
    """

    times_s: np.ndarray
    R_world_cam: np.ndarray
    yaw_rad: float
    gyro_bias_rad_s: np.ndarray
    R_mount: np.ndarray = field(default_factory=lambda: np.eye(3))
    reference_time_s: float = 0.0
    rate_rad_s: np.ndarray | None = None

    @classmethod
    def from_imu(cls, camera: PinholeCamera, time_s, gyro_rad_s, accel_m_s2, R_imu_cam, reference_time_s: float,
                 params: RegistrationParams = RegistrationParams()) -> "AttitudeTrack":
        """Filter the IMU samples and anchor the heading on the calibration at ``reference_time_s``.

        Parameters
        ----------
        camera : PinholeCamera
            The calibrated camera (intrinsics, optical centre, and its attitude at ``reference_time_s``).
        time_s, gyro_rad_s, accel_m_s2 : array_like
            IMU samples (see :func:`~planefuse.geometry.attitude_from_imu`).
        R_imu_cam : array_like, shape (3, 3)
            Camera -> IMU rotation.
        reference_time_s : float
            When the calibration holds (the first frame); the heading is fitted there, or at the end of the
            still start of the stream if that is later.
        params : RegistrationParams
        """
        t = np.asarray(time_s, dtype=float)
        bias = gyro_bias_at_rest(t, gyro_rad_s, params.gyro_bias_rest_s)
        reference_time_s = max(reference_time_s, t[0] + rest_at_start_s(t, gyro_rad_s, params.gyro_bias_rest_s))
        R_gravity_cam = attitude_from_imu(t, np.asarray(gyro_rad_s, dtype=float) - bias, accel_m_s2,
                                          method=params.imu_filter, R_imu_cam=R_imu_cam,
                                          params=dict(params.imu_filter_params or {}))
        k = int(np.clip(np.searchsorted(t, reference_time_s, side="right") - 1, 0, len(t) - 1))
        uv, xy = _ground_points_seen(camera)
        # keep the points whose rays also reach the ground with the filter's inclination
        down = (np.c_[uv, np.ones(len(uv))] @ np.linalg.inv(camera.K).T @ R_gravity_cam[k].T)[:, 2] < -1e-6
        if down.sum() < 2:
            raise ValueError(f"{camera.name}: the IMU attitude at t={t[k]:.3f} s sees the ground in fewer than 2 "
                             "of the calibration's ground points; is the IMU's T_cam_imu right?")
        yaw = yaw_from_ground_points(camera.K, R_gravity_cam[k], camera.center_world, uv[down], xy[down])
        R_world_cam = R_world_cam_from_attitude(R_gravity_cam, yaw)
        R_mount = R_world_cam[k].T @ camera.R_world_cam if params.refine_mount else np.eye(3)
        R_world_cam = R_world_cam @ R_mount
        R_world_cam[:k] = R_world_cam[k]  # the filter settling over the still start: the camera has not moved
        rate = np.linalg.norm(np.asarray(gyro_rad_s, dtype=float) - bias, axis=1)
        n = max(1, int(round(params.still_window_s / float(np.median(np.diff(t))))))
        mean_rate = np.convolve(rate, np.ones(n) / n)[: len(rate)]  # trailing mean (shorter at the start)
        return cls(t, R_world_cam, yaw, bias, R_mount, float(t[k]), mean_rate)

    def at(self, time_s: float) -> np.ndarray:
        """The attitude (3, 3) of the last IMU sample at or before ``time_s`` (the first before the stream)."""
        return self.R_world_cam[self._index(time_s)]

    def rate_at(self, time_s: float) -> float:
        """The mean rate [rad/s] at the last IMU sample at or before ``time_s`` (0 without rates)."""
        return 0.0 if self.rate_rad_s is None else float(self.rate_rad_s[self._index(time_s)])

    def _index(self, time_s: float) -> int:
        return max(int(np.searchsorted(self.times_s, time_s, side="right")) - 1, 0)


def _ground_points_seen(camera: PinholeCamera, n: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted pixels (M, 2) of ground points (z = 0) the calibrated camera sees, and their world XY.

    The points are where a grid of ``n x n`` pixels over the lower two thirds of the image meets the ground.
    """
    W, H = camera.intrinsics.width_px, camera.intrinsics.height_px
    u, v = np.meshgrid(np.linspace(0.1, 0.9, n) * (W - 1), np.linspace(0.35, 0.95, n) * (H - 1))
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    d = np.c_[uv, np.ones(len(uv))] @ np.linalg.inv(camera.K).T @ camera.R_world_cam.T
    c = camera.center_world
    down = d[:, 2] < -1e-6
    if down.sum() < 2:
        raise ValueError(f"{camera.name}: fewer than 2 image points see the ground; the heading cannot be fixed")
    xy = c[:2] + d[down, :2] * (-c[2] / d[down, 2])[:, None]
    return uv[down], xy


class CameraRegistration:
    """Every camera's image -> plane lookup over time, following the attitude where it comes from the IMU:
    the frames of a camera that turned are brought back to its calibrated view (:meth:`stabilise`), so that
    its lookup and its background model stay those of the calibration.

    Parameters
    ----------
    cameras : sequence of PinholeCamera
        The calibration (rest attitude and optical centre of every camera).
    stack : PlaneStack
    tracks : mapping of str -> AttitudeTrack
        The IMU attitude of every camera whose source is ``"imu"`` (by camera name).
    tolerance_px : float
        Rebuild threshold while a camera turns [px] (see the module docstring).
    still_tolerance_px : float, optional
        Rebuild threshold while its gyroscope says it is still [px] (at least ``tolerance_px``).
    still_rate_rad_s : float
        Mean rate below which a camera is still [rad/s].
    ignore_masks : sequence of (ndarray (height_px, width_px) bool or None), optional
        Per camera, pixels that are not scene evidence: every lookup leaves the cells they see unobserved
        (:meth:`ImagePlaneLookup.without_pixels`).
    occluder_boxes_m : array_like, shape (B, 6), optional
        Known static occluders ``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m]: every lookup leaves the
        cells whose line of sight from the camera's centre passes through one unobserved
        (:func:`planefuse.grid.cells_hidden_by_occluders`; a camera turning about its centre keeps them).

    Attributes
    ----------
    imu_gaps : dict of str -> list of Gap
        Per camera registered through its IMU, the gaps of its IMU stream (longer than 1.5 sample periods):
        the filter bridges each with one step over the gap (its gyroscope rate held), and they are reported
        (a warning per IMU, and the count in the run's metrics), never silently.
    n_rebuilds : list of int
        Stabilising maps rebuilt per camera (the cost of following the attitude besides one ``cv2.remap``
        per frame of a camera away from its calibrated attitude).
    rebuild_times_s : list of list of float
        Per camera, the instants [s] its stabilising map was rebuilt.
    """

    def __init__(self, cameras: Sequence[PinholeCamera], stack: PlaneStack,
                 tracks: Mapping[str, AttitudeTrack] | None = None, tolerance_px: float = 0.25,
                 ignore_masks: Sequence[np.ndarray | None] | None = None, still_tolerance_px: float | None = None,
                 still_rate_rad_s: float = float(np.radians(1.0)), occluder_boxes_m=None) -> None:
        self.cameras = list(cameras)
        self.occluder_boxes_m = check_occluder_boxes(occluder_boxes_m)
        if ignore_masks is not None and len(ignore_masks) != len(self.cameras):
            raise ValueError(f"ignore_masks: expected {len(self.cameras)} entries (None where absent), "
                             f"got {len(ignore_masks)}")
        self.ignore_masks = list(ignore_masks) if ignore_masks is not None else [None] * len(self.cameras)
        self.stack = stack
        self.tracks = dict(tracks or {})
        self.imu_gaps: dict[str, list] = {}
        unknown = set(self.tracks) - {c.name for c in self.cameras}
        if unknown:
            raise ValueError(f"attitude tracks for unknown cameras {sorted(unknown)}")
        self.tolerance_px = float(tolerance_px)
        self.still_tolerance_px = max(self.tolerance_px, float(still_tolerance_px or 0.0))
        self.still_rate_rad_s = float(still_rate_rad_s)
        self.n_rebuilds = [0] * len(self.cameras)
        self.rebuild_times_s: list[list[float]] = [[] for _ in self.cameras]
        self._built: list[np.ndarray | None] = [None] * len(self.cameras)
        self._maps: list[tuple[np.ndarray, np.ndarray, np.ndarray | None] | None] = [None] * len(self.cameras)
        self._rays: list[np.ndarray | None] = [None] * len(self.cameras)

    @classmethod
    def from_recording(cls, rec, stack: PlaneStack, params: RegistrationParams = RegistrationParams(),
                       occluder_boxes_m=None) -> "CameraRegistration":
        """The registration a :class:`~planefuse.io.Recording` and ``params`` call for (``occluder_boxes_m``:
        the known static occluders, see the class).

        Raises
        ------
        ValueError
            A camera whose source is ``"imu"`` has no IMU, or a camera named in ``attitude_source_by_camera``
            is not in the recording.
        """
        names = [c.name for c in rec.cameras]
        unknown = set(params.attitude_source_by_camera) - set(names)
        if unknown:
            raise ValueError(f"attitude_source_by_camera names cameras {sorted(unknown)} not in the recording "
                             f"(cameras: {names})")
        tracks, gaps = {}, {}
        for cam in rec.cameras:
            if params.source_of(cam.name) != "imu":
                continue
            imu = rec.imu_for(cam.name)
            data = imu.read()  # time order and finite samples checked: an error names the file and line
            gaps[cam.name] = list(imu.gaps)
            if imu.gaps:
                longest = max(g.before_s - g.after_s for g in imu.gaps)
                warnings.warn(f"{imu.name}: {len(imu.gaps)} gaps in the IMU stream ({sum(g.missing for g in imu.gaps)}"
                              f" samples missing, longest {longest:.3f} s); the attitude filter bridges each with "
                              "one step", stacklevel=2)
            t_ref = float(rec.camera(cam.name).times_s[0])
            R_imu_cam = np.asarray(imu.T_cam_imu, dtype=float)[:3, :3].T
            try:
                tracks[cam.name] = AttitudeTrack.from_imu(cam, data.times_s, data.gyro_rad_s, data.accel_m_s2,
                                                          R_imu_cam, t_ref, params)
            except ValueError as exc:
                raise ValueError(f"imu {imu.name!r} of camera {cam.name!r}: {exc}") from None
        out = cls(rec.cameras, stack, tracks, params.tolerance_px,
                  ignore_masks=[rec.camera(n).ignore_mask for n in names],
                  still_tolerance_px=params.still_tolerance_px, still_rate_rad_s=params.still_rate_rad_s,
                  occluder_boxes_m=occluder_boxes_m)
        out.imu_gaps = gaps
        return out

    @property
    def lookup_attitudes(self) -> list[np.ndarray | None]:
        """The attitude (3, 3) each camera's frames are currently stabilised from (the calibration's for a
        camera that follows none; None before :meth:`lookups_at`)."""
        return list(self._built)

    def attitude_at(self, camera_index: int, time_s: float) -> np.ndarray:
        """Camera ``camera_index``'s attitude (3, 3) at ``time_s`` from its source."""
        cam = self.cameras[camera_index]
        track = self.tracks.get(cam.name)
        return cam.R_world_cam if track is None else track.at(time_s)

    def lookup_for(self, camera_index: int) -> ImagePlaneLookup:
        """The lookup of camera ``camera_index`` at its calibrated attitude (lens distortion included)."""
        camera = self.cameras[camera_index]
        lookup = ImagePlaneLookup.from_camera(camera, self.stack)
        mask = self.ignore_masks[camera_index]
        if mask is not None:
            lookup = lookup.without_pixels(mask)
        if len(self.occluder_boxes_m):
            lookup = lookup.without_cells(cells_hidden_by_occluders(camera.center_world, self.stack,
                                                                    self.occluder_boxes_m))
        return lookup

    def lookups_at(self, time_s: float) -> list[ImagePlaneLookup]:
        """Every camera's lookup (the calibration's: :meth:`stabilise` brings the frames to it); the
        attitudes followed start from those at ``time_s``."""
        self._built = [self.attitude_at(c, time_s) for c in range(len(self.cameras))]
        self._maps = [None] * len(self.cameras)
        for c in self._following():
            self._maps[c] = self._stabilising_map(c, self._built[c])
        return [self.lookup_for(c) for c in range(len(self.cameras))]

    def stabilise(self, images: Sequence[np.ndarray | None], time_s: float) -> list[np.ndarray | None]:
        """The images of instant ``time_s`` (one per camera, None where missing) as each camera would have
        seen them at its calibrated attitude (call in time order, after :meth:`lookups_at`).

        A camera turning about its centre from its calibrated attitude ``R0`` to ``R`` sees the pixel of ray
        ``x0`` (camera frame at ``R0``) at ray ``R^T R0 x0``: the map from each calibrated pixel to the
        current image is rebuilt when the attitude has moved an image point by more than the tolerance since
        it was last built, and applied by ``cv2.remap`` (bilinear). Frames and foreground alike stay in the
        calibration's pixels, so the background models and the lookups stay valid; a camera at its calibrated
        attitude is passed through. The calibrated pixels the turned camera does not see (a strip along the
        border) repeat the border in the image; :meth:`unseen` names them, so that they give no evidence.
        """
        import cv2

        self._moved(time_s)
        out = list(images)
        for c, m in enumerate(self._maps):
            if m is None or out[c] is None:
                continue
            img = out[c]
            if img.dtype == np.float64:
                img = img.astype(np.float32)
            out[c] = cv2.remap(img, m[0], m[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return out

    def unseen(self, camera_index: int) -> np.ndarray | None:
        """Pixels (bool, (height_px, width_px)) of camera ``camera_index``'s calibrated view that its current
        frame does not see (it turned away from them), as of the last :meth:`stabilise`; None when it sees
        them all."""
        m = self._maps[camera_index]
        return None if m is None else m[2]

    def advance(self, times_s: Iterable[float]) -> None:
        """Follow the attitudes through ``times_s`` as :meth:`stabilise` would, without images (a resumed
        run replays the instants it skips so that its maps are those of the uninterrupted run)."""
        for t in times_s:
            self._moved(float(t))

    def _following(self) -> list[int]:
        return [c for c, cam in enumerate(self.cameras) if cam.name in self.tracks]

    def _stabilising_map(self, c: int, R_world_cam
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
        """``cv2.remap`` tables (float32, (H, W) each): for every pixel of the calibrated view, where it is in
        the image of camera ``c`` at attitude ``R_world_cam``, and the pixels with no source in that image
        (bool (H, W), None if there is none); None at the calibrated attitude itself."""
        cam = self.cameras[c]
        intr = cam.intrinsics
        if pixel_shift_px(cam.K, cam.R_world_cam, R_world_cam, intr.width_px, intr.height_px) < 1e-6:
            return None
        shape = (intr.height_px, intr.width_px)
        if self._rays[c] is None:  # the calibrated view's rays, camera frame: (x, y) per pixel, z = 1; float32
            u, v = np.meshgrid(np.arange(intr.width_px, dtype=float), np.arange(intr.height_px, dtype=float))
            xy = intr.normalized_from_pixels(np.stack([u.ravel(), v.ravel()], axis=1))
            self._rays[c] = xy.T.reshape(2, *shape).astype(np.float32)
        rx, ry = self._rays[c]
        M = (np.asarray(R_world_cam).T @ cam.R_world_cam).astype(np.float32)  # calibrated ray -> current camera
        x, y, z = (M[i, 0] * rx + M[i, 1] * ry + M[i, 2] for i in range(3))
        with np.errstate(divide="ignore", invalid="ignore"):
            d = distort_normalized(np.stack([x / z, y / z], axis=-1), intr.dist.astype(np.float32))
        K = cam.K.astype(np.float32)
        map_u = K[0, 0] * d[..., 0] + K[0, 1] * d[..., 1] + K[0, 2]
        map_v = K[1, 1] * d[..., 1] + K[1, 2]
        behind = z <= 1e-6  # no source
        map_u[behind] = map_v[behind] = -1e4
        # outside the current image by more than half a pixel: no source (the border is only repeated there)
        unseen = ((map_u < -0.5) | (map_u > intr.width_px - 0.5) | (map_v < -0.5)
                  | (map_v > intr.height_px - 0.5))
        return map_u, map_v, (unseen if unseen.any() else None)

    def _moved(self, time_s: float) -> list[int]:
        """Cameras whose attitude moved beyond the tolerance at ``time_s``; their map is rebuilt."""
        out = []
        for c in self._following():
            cam = self.cameras[c]
            R = self.attitude_at(c, time_s)
            built = self._built[c]
            turning = self.tracks[cam.name].rate_at(time_s) >= self.still_rate_rad_s
            tol = self.tolerance_px if turning else self.still_tolerance_px
            if built is not None and pixel_shift_px(cam.K, built, R, cam.intrinsics.width_px,
                                                    cam.intrinsics.height_px) <= tol:
                continue
            self._built[c] = R
            self._maps[c] = self._stabilising_map(c, R)
            self.n_rebuilds[c] += 1
            self.rebuild_times_s[c].append(float(time_s))
            out.append(c)
        return out
