"""Camera image formation: textured static room, shaded people, shadows, lighting and sensor noise.

The background (floor tiles, walls, what is above the walls) is ray cast once per camera through
planefuse's camera model, supersampled 2x2 against aliasing. Each frame then draws the people over it
in painter's order (farthest first): every body volume is sampled on its surface (circumscribed rings
for cylinders, a point cloud for the head sphere), projected with :meth:`PinholeCamera.project`, and its
silhouette is the convex hull of those pixels (filled with :func:`cv2.fillConvexPoly`). The same hull is
written into the label image, which is the exact ground-truth foreground mask: ``labels == pid + 1``
where person ``pid`` is the visible surface, 0 on the background. Shading (Lambertian facets), a soft
global illumination drift, per-frame gain flicker and per-pixel noise are applied to the colour image
only.

Static occluders (the scene's boxes) are ray cast into the background (flat colour, Lambertian per face)
and, per pixel, their horizontal distance from the camera is kept: a person's pixel whose body centre
lies farther than the occluder surface seen through that pixel is painted back with the occluder and
removed from the label image (so the masks are exact up to the person's own depth, ~0.15 m).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.ndimage import map_coordinates

from ..geometry import CameraIntrinsics, PinholeCamera, transform_from_rotation_translation
from ..laser import HIT_BOX, raycast
from ._config import RenderSpec
from ._motion import R_world_cam_at, max_motion_deg
from ._scene import Body, Scene

__all__ = ["CameraRenderer", "body_surface_points", "occluder_distance_image", "N_RING"]

#: Vertices per cylinder ring; rings are circumscribed so that the polygon contains the circle.
N_RING = 16
_LIGHT = np.array([0.6, 0.4, 0.7]) / np.linalg.norm([0.6, 0.4, 0.7])
_SUBPIXEL_BITS = 4
_SPHERE_N = 64


def _fibonacci_sphere(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    a = np.pi * (1 + 5**0.5) * i
    return np.stack([r * np.cos(a), r * np.sin(a), z], axis=1)


_UNIT_SPHERE = _fibonacci_sphere(_SPHERE_N)
# Scale so that the point cloud's hull contains the sphere (max angular gap of a 64-point Fibonacci set ~ 17 deg).
_SPHERE_SCALE = 1.0 / np.cos(np.radians(17.0))
_RING_ANG = np.arange(N_RING) * 2 * np.pi / N_RING
_RING_SCALE = 1.0 / np.cos(np.pi / N_RING)
_FACET_NORMALS = np.stack([np.cos(_RING_ANG + np.pi / N_RING), np.sin(_RING_ANG + np.pi / N_RING)], axis=1)
_HAIR = _UNIT_SPHERE[:, 2] > 0.2


def body_surface_points(cylinders: np.ndarray, spheres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Surface sample points whose convex hull (in 3-D) contains each body volume.

    Parameters
    ----------
    cylinders : ndarray, shape (C, 5)
        ``[x_m, y_m, radius_m, z_bottom_m, z_top_m]``.
    spheres : ndarray, shape (S, 4)
        ``[x_m, y_m, z_m, radius_m]``.

    Returns
    -------
    cyl_points : ndarray, shape (C, 3, N_RING, 3)
        Bottom, middle and top rings of each cylinder (world, metres).
    sph_points : ndarray, shape (S, 64, 3)
        Points around each sphere.
    """
    C = len(cylinders)
    ring = np.stack([np.cos(_RING_ANG), np.sin(_RING_ANG)], axis=1) * _RING_SCALE
    cyl = np.zeros((C, 3, N_RING, 3))
    r = cylinders[:, 2][:, None, None, None]
    cyl[..., :2] = cylinders[:, None, None, :2] + r * ring[None, None]
    zb, zt = cylinders[:, 3], cylinders[:, 4]
    cyl[..., 2] = np.stack([zb, 0.5 * (zb + zt), zt], axis=1)[:, :, None]
    sph = spheres[:, None, :3] + spheres[:, 3, None, None] * _SPHERE_SCALE * _UNIT_SPHERE[None]
    return cyl, sph


def _value_noise(rng: np.random.Generator, shape: tuple[int, int], coords: np.ndarray) -> np.ndarray:
    """Smooth random field sampled at fractional grid coordinates (2, N) (cubic spline interpolation)."""
    grid = rng.normal(size=shape)
    return map_coordinates(grid, coords, order=3, mode="wrap")


def _interp_grid(coarse: np.ndarray, nx: int, ny: int, step: int) -> np.ndarray:
    """Bilinear upsampling of values on grid nodes ``k * step`` to every integer index (ny, nx, C)."""
    fx = np.arange(nx) / step
    fy = np.arange(ny) / step
    ix = np.minimum(fx.astype(int), coarse.shape[1] - 2)
    iy = np.minimum(fy.astype(int), coarse.shape[0] - 2)
    wx = (fx - ix)[None, :, None]
    wy = (fy - iy)[:, None, None]
    a = coarse[iy][:, ix]
    b = coarse[iy][:, ix + 1]
    c = coarse[iy + 1][:, ix]
    d = coarse[iy + 1][:, ix + 1]
    return (a * (1 - wx) + b * wx) * (1 - wy) + (c * (1 - wx) + d * wx) * wy


def _pixel_rays(camera: PinholeCamera, ss: int) -> np.ndarray:
    """Unit rays in {W} (H*ss*W*ss, 3) through the centres of ``ss x ss`` supersamples of every pixel.

    Lens distortion is smooth: it is inverted on a coarse grid (every 4 supersamples) and interpolated.
    """
    W, H = camera.intrinsics.width_px, camera.intrinsics.height_px
    step = 4
    gu = (np.arange(0, W * ss + step, step) + 0.5) / ss - 0.5
    gv = (np.arange(0, H * ss + step, step) + 0.5) / ss - 0.5
    u, v = np.meshgrid(gu, gv)
    coarse = camera.rays(np.stack([u.ravel(), v.ravel()], axis=1)).reshape(len(gv), len(gu), 3)
    d = _interp_grid(coarse, W * ss, H * ss, step).reshape(-1, 3)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _box_hits(camera: PinholeCamera, d: np.ndarray, boxes: np.ndarray, room_xy_m, wall_height_m: float):
    """Range [m] (inf where none), box index and outward face normal (N, 3) of the first occluder on each ray."""
    c = camera.center_world
    r, kind, idx = raycast(np.broadcast_to(c, d.shape), d, None, None, room_xy_m, wall_height_m, 1e3,
                           boxes=boxes, return_hits=True)
    hit = kind == HIT_BOX
    r = np.where(hit, r, np.inf)
    normal = np.zeros(d.shape)
    if hit.any():
        p = c + r[hit, None] * d[hit]
        b = boxes[idx[hit]]
        # the face whose plane the hit point lies on: smallest distance to a face plane, sign = side
        dist = np.abs(np.stack([p[:, 0] - b[:, 0], p[:, 0] - b[:, 1], p[:, 1] - b[:, 2], p[:, 1] - b[:, 3],
                                p[:, 2] - b[:, 4], p[:, 2] - b[:, 5]], axis=1))
        face = np.argmin(dist, axis=1)
        n = np.zeros((len(face), 3))
        n[np.arange(len(face)), face // 2] = np.where(face % 2 == 0, -1.0, 1.0)
        normal[hit] = n
    return r, np.where(hit, idx, -1), normal


def occluder_distance_image(camera: PinholeCamera, boxes, room_xy_m, wall_height_m: float) -> np.ndarray:
    """Horizontal distance [m] from the camera centre to the occluder surface seen through each pixel centre,
    (H, W) float64, ``inf`` where no occluder is seen. ``boxes`` (B, 6) as in :func:`planefuse.laser.raycast`."""
    W, H = camera.intrinsics.width_px, camera.intrinsics.height_px
    d = _pixel_rays(camera, 1)
    r, _, _ = _box_hits(camera, d, np.asarray(boxes, dtype=float).reshape(-1, 6), room_xy_m, wall_height_m)
    return (r * np.hypot(d[:, 0], d[:, 1])).reshape(H, W)


def render_background(camera: PinholeCamera, room_xy_m, wall_height_m: float, seed: int, boxes=None,
                      boxes_bgr=None, vignetting: bool = True) -> np.ndarray:
    """Ray cast the empty room seen by ``camera``: (H, W, 3) uint8 BGR.

    Floor: 0.5 m tiles with grout, per-tile tone and smooth mottling, lit from the middle of the
    room. Walls: per-wall paint with panels and a dark skirting board. Above the walls: a dim
    grey-blue gradient. Occluders (``boxes`` (B, 6) ``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m],
    colours ``boxes_bgr`` (B, 3)): flat colour with Lambertian shading per face. ``vignetting``: darken
    towards the corners as a lens does (off for the wide views that moving cameras resample).
    """
    W, H = camera.intrinsics.width_px, camera.intrinsics.height_px
    ss = 2
    d = _pixel_rays(camera, ss)
    c = camera.center_world
    x0, x1, y0, y1 = room_xy_m
    n = len(d)
    best_t = np.full(n, np.inf)
    surf = np.full(n, -1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -c[2] / d[:, 2]
        ok = (d[:, 2] < 0) & (t > 0)
        best_t[ok], surf[ok] = t[ok], 0
        for k, (axis, val) in enumerate([(0, x0), (0, x1), (1, y0), (1, y1)], start=1):
            t = (val - c[axis]) / d[:, axis]
            hit = c + t[:, None] * d
            other = hit[:, 1 - axis]
            lo, hi = (y0, y1) if axis == 0 else (x0, x1)
            ok = (t > 1e-6) & (t < best_t) & (hit[:, 2] >= 0) & (hit[:, 2] <= wall_height_m)
            ok &= (other >= lo) & (other <= hi)
            best_t[ok], surf[ok] = t[ok], k
    p = c + np.where(np.isfinite(best_t), best_t, 0.0)[:, None] * d
    rng = np.random.default_rng([seed, 7])
    img = np.zeros((n, 3))

    # Floor.
    f = surf == 0
    pf = p[f]
    tile = 0.5
    ix = np.floor(pf[:, 0] / tile).astype(int)
    iy = np.floor(pf[:, 1] / tile).astype(int)
    tone = np.random.default_rng([seed, 8]).uniform(-12, 12, size=(64, 64))[ix % 64, iy % 64]
    checker = np.where((ix + iy) % 2 == 0, 0.0, -18.0)
    mott = _value_noise(rng, (64, 64), np.stack([pf[:, 0] / 0.25, pf[:, 1] / 0.25])) * 10
    fx = np.abs(pf[:, 0] / tile - np.round(pf[:, 0] / tile)) * tile
    fy = np.abs(pf[:, 1] / tile - np.round(pf[:, 1] / tile)) * tile
    grout = np.minimum(fx, fy) < 0.012
    base = np.array([150.0, 165.0, 175.0])
    col = base[None] + (tone + checker + mott)[:, None]
    col[grout] *= 0.6
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    light = 0.75 + 0.25 * np.exp(-((pf[:, 0] - cx) ** 2 + (pf[:, 1] - cy) ** 2) / (2 * (0.4 * (x1 - x0)) ** 2))
    img[f] = col * light[:, None]

    # Walls.
    wall_bgr = np.array([[120, 150, 170], [150, 140, 120], [110, 130, 110], [160, 160, 150]], dtype=float)
    for k in range(1, 5):
        w = surf == k
        pw = p[w]
        s = pw[:, 1] if k <= 2 else pw[:, 0]
        z = pw[:, 2]
        col = wall_bgr[k - 1][None] + _value_noise(rng, (64, 16), np.stack([s / 0.3, z / 0.3]))[:, None] * 8
        panel = (np.abs(s / 1.2 - np.round(s / 1.2)) * 1.2 < 0.02) & (z > 0.12)
        col[panel] *= 0.8
        col[z < 0.12] = (60, 55, 50)
        shade = 0.7 + 0.3 * np.clip(z / wall_height_m, 0, 1)
        img[w] = col * shade[:, None]

    # Above the walls.
    a = surf < 0
    elev = np.clip(d[a, 2], -1, 1)
    img[a] = np.array([120.0, 105.0, 95.0])[None] + 40 * elev[:, None]

    # Occluders (inside the room: in front of any floor or wall).
    boxes = np.asarray(boxes if boxes is not None else np.zeros((0, 6)), dtype=float).reshape(-1, 6)
    if len(boxes):
        _, idx, normal = _box_hits(camera, d, boxes, room_xy_m, wall_height_m)
        b = idx >= 0
        bgr = np.asarray(boxes_bgr, dtype=float).reshape(-1, 3)
        img[b] = bgr[idx[b]] * (0.55 + 0.45 * np.abs(normal[b] @ _LIGHT))[:, None]

    img = img.reshape(H * ss, W * ss, 3).astype(np.float32)
    img = cv2.resize(img, (W, H), interpolation=cv2.INTER_AREA)
    if vignetting:
        img *= _vignetting(W, H)[..., None]
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def _vignetting(W: int, H: int) -> np.ndarray:
    """Lens vignetting gain (H, W) float32: 1 at the centre, 0.75 in the corners."""
    yy, xx = np.mgrid[0:H, 0:W]
    r2 = ((xx - W / 2) ** 2 + (yy - H / 2) ** 2) / ((W / 2) ** 2 + (H / 2) ** 2)
    return (1.0 - 0.25 * r2).astype(np.float32)


def _poly(uv: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) -> int32 fixed-point polygon for cv2 drawing with ``_SUBPIXEL_BITS``."""
    return np.round(np.clip(uv, -4000, 4000) * (1 << _SUBPIXEL_BITS)).astype(np.int32)


class CameraRenderer:
    """Renders frames and exact label masks of a :class:`Scene` for one camera.

    Parameters
    ----------
    camera : PinholeCamera
    scene : Scene
    render : RenderSpec
        Lighting and noise settings.
    seed : int
        Makes the noise reproducible; frame ``k`` always renders the same image.
    camera_index : int
        Distinguishes the noise streams of cameras sharing a seed.
    noise_bank : ndarray, shape (B, H, W, 3), uint8, optional
        Pre-drawn pixel noise images centred on 128 (shared between cameras of one size).
    motion : sequence of CameraMotionSpec, optional
        The camera turns about its centre from the attitude of ``camera`` (its rest attitude, what the
        calibration says) as :func:`planefuse.sim._motion.R_world_cam_at` gives. The empty room is then ray
        cast once for a wider view at rest and resampled per frame along the moved camera's pixel rays.
    """

    def __init__(
        self,
        camera: PinholeCamera,
        scene: Scene,
        render: RenderSpec,
        seed: int,
        camera_index: int = 0,
        noise_bank: np.ndarray | None = None,
        motion=(),
    ) -> None:
        self.camera = camera
        self.motion = tuple(motion)
        self._wide: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.scene = scene
        self.spec = render
        self.seed = seed
        self.camera_index = camera_index
        self._background: np.ndarray | None = None
        self._occluder_distance: np.ndarray | None = None
        T_cam_world = camera.T_cam_world
        self._R_cam_world, self._t_cam_world = T_cam_world[:3, :3].copy(), T_cam_world[:3, 3].copy()
        W, H = camera.intrinsics.width_px, camera.intrinsics.height_px
        if noise_bank is None:
            noise_bank = make_noise_bank(W, H, render.pixel_noise_std, seed)
        if noise_bank.shape[1:] != (H, W, 3):
            raise ValueError(f"noise_bank must have shape (B, {H}, {W}, 3), got {noise_bank.shape}")
        self.noise_bank = noise_bank
        self._shades = [self._shade_table(b) for b in scene.bodies]
        self._phase = np.random.default_rng([seed, 3, camera_index]).uniform(0, 2 * np.pi)

    def project(self, p_world: np.ndarray) -> np.ndarray:
        """:meth:`PinholeCamera.project` of points (N, 3) with the inverse pose computed once (hot path)."""
        pc = p_world @ self._R_cam_world.T + self._t_cam_world
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = self.camera.intrinsics.pixels_from_normalized(pc[:, :2] / z[:, None])
        uv[z <= 0] = np.nan
        return uv

    @property
    def background(self) -> np.ndarray:
        """The empty room (H, W, 3) uint8 BGR seen at the rest attitude, ray cast on first use."""
        if self._background is None:
            if self.motion:
                self._background = self._background_at(self.camera.R_world_cam)
            else:
                sc = self.scene
                self._background = render_background(
                    self.camera, sc.room_xy_m, sc.wall_height_m, self.seed + 101 * self.camera_index,
                    sc.occluder_boxes_m, [o.bgr for o in sc.config.occluders])
        return self._background

    def R_world_cam_at(self, time_s: float) -> np.ndarray:
        """The camera's attitude (3, 3) at ``time_s`` (its calibrated one when it does not move)."""
        if not self.motion:
            return self.camera.R_world_cam
        return R_world_cam_at(self.camera.R_world_cam, self.motion, [time_s])[0]

    def _background_at(self, R_world_cam: np.ndarray) -> np.ndarray:
        """Empty room seen with attitude ``R_world_cam`` (the camera turns about its centre): the wide rest view
        resampled along this attitude's pixel rays, then vignetted."""
        if self._wide is None:
            self._wide = self._wide_view()
        wide, K_wide, d_cam = self._wide
        R0 = self.camera.R_world_cam
        d = d_cam @ (R0.T @ R_world_cam).T  # pixel rays in the wide (rest) camera frame
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = d[:, :2] / d[:, 2:3] @ K_wide[:2, :2].T + K_wide[:2, 2]
        uv[d[:, 2] <= 0] = -1.0
        W, H = self.camera.intrinsics.width_px, self.camera.intrinsics.height_px
        maps = uv.reshape(H, W, 2).astype(np.float32)
        img = cv2.remap(wide, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        img = img.astype(np.float32) * _vignetting(W, H)[..., None]
        return np.clip(np.round(img), 0, 255).astype(np.uint8)

    def _wide_view(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The empty room (no vignetting) from the rest attitude through an undistorted pinhole wide enough for
        every attitude of the motion; its K; the camera's pixel rays in its own frame (H*W, 3)."""
        cam = self.camera
        W, H = cam.intrinsics.width_px, cam.intrinsics.height_px
        u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
        xy = cam.intrinsics.normalized_from_pixels(np.stack([u.ravel(), v.ravel()], axis=1))
        d_cam = np.c_[xy, np.ones(len(xy))]
        margin = np.radians(max_motion_deg(self.motion) + 3.0)
        half = np.arctan(np.abs(xy).max(axis=0)) + margin
        if np.any(half >= np.radians(80.0)):
            raise ValueError(f"{cam.name}: the camera's motion ({max_motion_deg(self.motion):.1f} deg) turns its "
                             "view too far to be rendered (over 80 deg off its rest axis)")
        f = float(cam.K[0, 0])
        Ww, Hw = (2 * np.ceil(f * np.tan(half))).astype(int) + 1
        K_wide = np.array([[f, 0.0, (Ww - 1) / 2], [0.0, f, (Hw - 1) / 2], [0.0, 0.0, 1.0]])
        wide_cam = PinholeCamera(CameraIntrinsics(K_wide, int(Ww), int(Hw)),
                                 transform_from_rotation_translation(cam.R_world_cam, cam.center_world))
        sc = self.scene
        wide = render_background(wide_cam, sc.room_xy_m, sc.wall_height_m, self.seed + 101 * self.camera_index,
                                 sc.occluder_boxes_m, [o.bgr for o in sc.config.occluders], vignetting=False)
        return wide, K_wide, d_cam

    @property
    def occluder_distance(self) -> np.ndarray | None:
        """:func:`occluder_distance_image` of the scene's occluders (None without occluders), computed once."""
        sc = self.scene
        if len(sc.occluder_boxes_m) and self.motion:
            raise ValueError(f"{self.camera.name}: a moving camera in a scene with occluders is not simulated "
                             "(occluder masks are cast from the rest attitude)")
        if len(sc.occluder_boxes_m) == 0:
            return None
        if self._occluder_distance is None:
            self._occluder_distance = occluder_distance_image(self.camera, sc.occluder_boxes_m, sc.room_xy_m,
                                                              sc.wall_height_m)
        return self._occluder_distance

    def gain(self, time_s: float, rng: np.random.Generator) -> float:
        """Global illumination gain at ``time_s``: slow drift plus per-frame flicker."""
        s = self.spec
        return float(
            1.0
            + s.gain_drift * np.sin(2 * np.pi * time_s / s.gain_drift_period_s + self._phase)
            + s.gain_flicker_std * rng.normal()
        )

    def labels(self, time_s: float) -> np.ndarray:
        """Ground-truth label image (H, W) uint8 at ``time_s``: 0 background, ``pid + 1`` for person ``pid``."""
        return self._draw(time_s, colour=False)[1]

    def render(self, time_s: float, frame_index: int) -> tuple[np.ndarray, np.ndarray]:
        """Image (H, W, 3) uint8 BGR and label mask (H, W) uint8 at ``time_s``.

        ``frame_index`` seeds the frame's noise so that rendering is reproducible in any order.
        """
        clean, labels = self._draw(time_s, colour=True)
        rng = np.random.default_rng([self.seed, 2, self.camera_index, frame_index])
        noise = self.noise_bank[int(rng.integers(len(self.noise_bank)))]
        img = cv2.addWeighted(clean, self.gain(time_s, rng), noise, 1.0, -128.0, dtype=cv2.CV_8U)
        return img, labels

    def _draw(self, time_s: float, colour: bool) -> tuple[np.ndarray | None, np.ndarray]:
        cam = self.camera
        W, H = cam.intrinsics.width_px, cam.intrinsics.height_px
        labels = np.zeros((H, W), np.uint8)
        if self.motion:  # the pose :meth:`project` uses, at this frame's time
            R = self.R_world_cam_at(time_s)
            self._R_cam_world, self._t_cam_world = R.T, -R.T @ cam.center_world
            img = self._background_at(R) if colour else None
        else:
            img = self.background.copy() if colour else None
        P = self.scene.n_people
        if P == 0:
            return img, labels
        cyl, _, sph, _ = self.scene.bodies_at(time_s)
        cyl_pts, sph_pts = body_surface_points(cyl, sph)
        # One projection and one fixed-point conversion for every sample point of the frame.
        n_c = cyl_pts.reshape(-1, 3).shape[0]
        uv = self.project(np.concatenate([cyl_pts.reshape(-1, 3), sph_pts.reshape(-1, 3)]))
        ok = np.isfinite(uv).all(axis=1)
        fx = _poly(np.where(ok[:, None], uv, 0.0))
        fx_cyl, ok_cyl = fx[:n_c].reshape(len(cyl), 3 * N_RING, 2), ok[:n_c].reshape(len(cyl), 3 * N_RING)
        fx_sph, ok_sph = fx[n_c:].reshape(P, _SPHERE_N, 2), ok[n_c:].reshape(P, _SPHERE_N)
        c = cam.center_world
        if colour:
            if self.spec.shadows:
                self._shadows(img, cyl)
            # Side facets facing the camera (normals between ring vertices i and i+1), for all cylinders at once.
            mid = 0.5 * (cyl_pts[:, 1, :, :2] + np.roll(cyl_pts[:, 1, :, :2], -1, axis=1))
            facing = np.einsum("ij,cij->ci", _FACET_NORMALS, c[:2] - mid) > 0
            nxt = (np.arange(N_RING) + 1) % N_RING
            ring_b, ring_t = fx_cyl[:, :N_RING], fx_cyl[:, 2 * N_RING :]
            quads = np.stack([ring_b, ring_b[:, nxt], ring_t[:, nxt], ring_t], axis=2)  # (C, N_RING, 4, 2)
            quad_ok = ok_cyl[:, :N_RING] & ok_cyl[:, :N_RING][:, nxt] & ok_cyl[:, 2 * N_RING :]
            quad_ok &= ok_cyl[:, 2 * N_RING :][:, nxt]
        order = np.argsort(-np.hypot(sph[:, 0] - c[0], sph[:, 1] - c[1]))  # farthest person first
        for pid in order:
            body = self.scene.bodies[pid]
            shade = self._shades[pid]
            legs = sorted((3 * pid, 3 * pid + 1), key=lambda j: -np.hypot(cyl[j, 0] - c[0], cyl[j, 1] - c[1]))
            for j, part in ((legs[0], 0), (legs[1], 0), (3 * pid + 2, 1)):
                if ok_cyl[j].sum() < 3:
                    continue
                hull = cv2.convexHull(fx_cyl[j][ok_cyl[j]])
                cv2.fillConvexPoly(labels, hull, int(pid) + 1, cv2.LINE_8, _SUBPIXEL_BITS)
                if not colour:
                    continue
                if part == 0:  # legs are a few pixels wide: one flat colour
                    cv2.fillConvexPoly(img, hull, shade[0][N_RING + 1], cv2.LINE_8, _SUBPIXEL_BITS)
                    continue
                cv2.fillConvexPoly(img, hull, shade[part][-1], cv2.LINE_8, _SUBPIXEL_BITS)
                for i in np.nonzero(facing[j] & quad_ok[j])[0]:
                    cv2.fillConvexPoly(img, quads[j, i], shade[part][i], cv2.LINE_8, _SUBPIXEL_BITS)
                if c[2] > cyl[j, 4] and ok_cyl[j, 2 * N_RING :].all():
                    cv2.fillConvexPoly(img, ring_t[j], shade[part][N_RING], cv2.LINE_8, _SUBPIXEL_BITS)
            if ok_sph[pid].sum() < 3:
                continue
            hull = cv2.convexHull(fx_sph[pid][ok_sph[pid]])
            cv2.fillConvexPoly(labels, hull, int(pid) + 1, cv2.LINE_8, _SUBPIXEL_BITS)
            if colour:
                cv2.fillConvexPoly(img, hull, body.skin_bgr, cv2.LINE_8, _SUBPIXEL_BITS)
                cap = _HAIR & ok_sph[pid]
                if cap.sum() >= 3:
                    cv2.fillConvexPoly(img, cv2.convexHull(fx_sph[pid][cap]), body.hair_bgr, cv2.LINE_8, _SUBPIXEL_BITS)
        occ = self.occluder_distance
        if occ is not None:
            # a person's pixel is hidden where the occluder surface is nearer than the person's centre
            person_dist = np.append(np.inf, np.hypot(sph[:, 0] - c[0], sph[:, 1] - c[1]))
            hide = np.isfinite(occ) & ((labels == 0) | (person_dist[labels] > occ))
            labels[hide] = 0
            if colour:
                img[hide] = self.background[hide]
        return img, labels

    def _shadows(self, img: np.ndarray, cyl: np.ndarray) -> None:
        """Darken the floor under each person (blurred ellipses, by up to 45 grey levels): not foreground."""
        torso = cyl[2::3]
        P = len(torso)
        ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        rad = (torso[:, 2] * 1.6)[:, None]
        pts = np.zeros((P, 16, 3))
        pts[..., 0] = torso[:, 0, None] + rad * np.cos(ang)
        pts[..., 1] = torso[:, 1, None] + rad * 1.3 * np.sin(ang)
        uv = self.project(pts.reshape(-1, 3)).reshape(P, 16, 2)
        uv = uv[np.isfinite(uv).all(axis=(1, 2))]
        if not len(uv):
            return
        H, W = img.shape[:2]
        x0, y0 = np.maximum(np.floor(uv.min(axis=(0, 1))).astype(int) - 4, 0)
        x1, y1 = np.minimum(np.ceil(uv.max(axis=(0, 1))).astype(int) + 5, (W, H))
        if x1 <= x0 or y1 <= y0:
            return
        m = np.zeros((y1 - y0, x1 - x0), np.uint8)
        for q in uv:
            cv2.fillConvexPoly(m, _poly(q - (x0, y0)), 45, cv2.LINE_AA, _SUBPIXEL_BITS)
        m = cv2.GaussianBlur(m, (0, 0), 1.5)
        roi = img[y0:y1, x0:x1]
        cv2.subtract(roi, cv2.cvtColor(m, cv2.COLOR_GRAY2BGR), dst=roi)

    @staticmethod
    def _shade_table(body: Body) -> list[list[list[list[float]]]]:
        """Per part (legs, torso): colours of the N_RING side facets, the top cap, the mean side shade and the
        silhouette fill (the darkest shade, seen only between facets)."""
        lam = 0.5 + 0.5 * np.clip(_FACET_NORMALS @ _LIGHT[:2], 0.0, 1.0)
        out = []
        for bgr in (body.leg_bgr, body.torso_bgr):
            base = np.asarray(bgr, dtype=float)
            rows = [base * x for x in lam] + [base * (0.5 + 0.5 * _LIGHT[2]), base * lam.mean(), base * 0.5]
            out.append([r.tolist() for r in rows])
        return out

def make_noise_bank(width_px: int, height_px: int, std: float, seed: int, n: int = 16) -> np.ndarray:
    """``n`` images (n, H, W, 3) uint8 of Gaussian pixel noise with standard deviation ``std`` centred on 128."""
    rng = np.random.default_rng([seed, 4, width_px, height_px])
    noise = rng.normal(128.0, std, size=(n, height_px, width_px, 3)).astype(np.float32)
    return np.clip(np.round(noise), 0, 255).astype(np.uint8)
