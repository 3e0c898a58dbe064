"""People (bodies of a few volumes) walking in a walled room: the simulator's ground truth.

World frame: the room's floor corner is the origin, x and y along the walls, z up against gravity,
metres. A person is two legs and a torso (vertical cylinders) and a head (a sphere); the legs swing
apart along the walking direction with a gait phase that advances with the distance walked, so
planes at different heights cut different cross-sections. Trajectories come from a small social-force
model: each person walks at their preferred speed towards a random goal, sometimes stops there,
turns smoothly, keeps away from the walls and roughly avoids the others; people stop to talk.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._config import SceneConfig

__all__ = ["Body", "Scene", "PeopleState", "sample_points_in_bodies"]

#: Internal integration step of the walking model [s]; states are interpolated between steps.
DT_S = 0.02
#: Horizontal distance walked per full gait cycle (two steps) [m].
STRIDE_M = 1.3
#: Speakers start stopping this long before they speak, so that they stand (nearly) still while talking [s].
STOP_BEFORE_SPEAKING_S = 1.0


@dataclass(frozen=True)
class Body:
    """Static shape of one person [m] and clothing colours (BGR, 0-255)."""

    person_id: int
    height_m: float
    hip_height_m: float
    leg_radius_m: float
    leg_spacing_m: float
    torso_radius_m: float
    head_radius_m: float
    leg_bgr: tuple[int, int, int]
    torso_bgr: tuple[int, int, int]
    skin_bgr: tuple[int, int, int]
    hair_bgr: tuple[int, int, int]

    @property
    def torso_top_m(self) -> float:
        """Top of the torso cylinder = bottom of the head sphere [m]."""
        return self.height_m - 2.0 * self.head_radius_m

    @property
    def head_center_z_m(self) -> float:
        return self.height_m - self.head_radius_m


@dataclass(frozen=True)
class PeopleState:
    """People at a batch of times (T,): positions ``xy_m`` (T, P, 2), ``heading_rad`` (T, P) (direction of the
    body's front, counter-clockwise from +x), ``speed_m_s`` (T, P), ``gait_phase_rad`` (T, P)."""

    times_s: np.ndarray
    xy_m: np.ndarray
    heading_rad: np.ndarray
    speed_m_s: np.ndarray
    gait_phase_rad: np.ndarray


def _random_bodies(cfg: SceneConfig, rng: np.random.Generator) -> list[Body]:
    lo, hi = cfg.people.height_range_m
    # Clothing colours far from the floor/wall palette so that people are findable but not trivially.
    trousers = [(60, 40, 30), (40, 40, 40), (120, 90, 60), (50, 60, 110), (90, 90, 90), (30, 30, 70)]
    shirts = [(40, 40, 190), (180, 120, 40), (60, 160, 60), (200, 200, 200), (30, 150, 220), (140, 60, 140),
              (90, 90, 50), (210, 180, 160)]
    skins = [(140, 170, 220), (110, 140, 190), (70, 100, 150), (160, 190, 235)]
    hairs = [(20, 20, 25), (40, 60, 90), (30, 30, 30), (120, 150, 180)]
    out = []
    for pid in range(cfg.n_people):
        h = float(rng.uniform(lo, hi))
        s = h / 1.75
        out.append(
            Body(
                person_id=pid,
                height_m=h,
                hip_height_m=0.50 * h,
                leg_radius_m=float(0.065 * s * rng.uniform(0.9, 1.1)),
                leg_spacing_m=float(0.2 * s),
                torso_radius_m=float(0.18 * s * rng.uniform(0.9, 1.15)),
                head_radius_m=float(0.105 * s),
                leg_bgr=trousers[int(rng.integers(len(trousers)))],
                torso_bgr=shirts[int(rng.integers(len(shirts)))],
                skin_bgr=skins[int(rng.integers(len(skins)))],
                hair_bgr=hairs[int(rng.integers(len(hairs)))],
            )
        )
    return out


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


#: People keep at least this distance [m] from an occluder's faces (their torso radius and a little).
OCCLUDER_CLEARANCE_M = 0.3


def _nearest_on_boxes(p: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest point of each box footprint to each position and its distance.

    ``p`` (P, 2) [m], ``boxes`` (B, 6) ``[x_min, x_max, y_min, y_max, z_min, z_max]``; returns ``q``
    (P, B, 2) and ``dist`` (P, B) [m] (0 inside a footprint).
    """
    q = np.stack([np.clip(p[:, None, 0], boxes[None, :, 0], boxes[None, :, 1]),
                  np.clip(p[:, None, 1], boxes[None, :, 2], boxes[None, :, 3])], axis=-1)
    return q, np.linalg.norm(p[:, None, :] - q, axis=-1)


def _free_of_boxes(xy: np.ndarray, boxes: np.ndarray, clearance_m: float) -> np.ndarray:
    """True where a position (N, 2) is farther than ``clearance_m`` from every box footprint."""
    if len(boxes) == 0:
        return np.ones(len(xy), bool)
    return _nearest_on_boxes(xy, boxes)[1].min(axis=1) > clearance_m


def _sample_free(rng: np.random.Generator, lo_xy, hi_xy, boxes: np.ndarray, n: int) -> np.ndarray:
    """``n`` uniform positions in ``[lo_xy, hi_xy]`` clear of the occluders (rejection sampling)."""
    out = rng.uniform(lo_xy, hi_xy, size=(n, 2))
    for _ in range(100):
        bad = ~_free_of_boxes(out, boxes, OCCLUDER_CLEARANCE_M + 0.2)
        if not bad.any():
            break
        out[bad] = rng.uniform(lo_xy, hi_xy, size=(int(bad.sum()), 2))
    return out


def _walk(cfg: SceneConfig, bodies: list[Body], rng: np.random.Generator) -> PeopleState:
    """Integrate the walking model on the grid ``k * DT_S`` covering the whole duration.

    Occluders: goals and starts are drawn clear of them; within 0.6 m of a box a person's desired velocity
    loses its component into the box (they slide along its face), an exponential force pushes them off and
    a hard constraint keeps them ``OCCLUDER_CLEARANCE_M`` away.
    """
    boxes = np.array([o.box_m() for o in cfg.occluders], dtype=float).reshape(-1, 6)
    P = len(bodies)
    n = int(np.ceil(cfg.duration_s / DT_S)) + 2
    t = np.arange(n) * DT_S
    x0, x1, y0, y1 = cfg.room_xy_m
    m = cfg.people.wall_margin_m
    lo_xy = np.array([x0 + m, y0 + m])
    hi_xy = np.array([x1 - m, y1 - m])
    xy = np.zeros((n, P, 2))
    heading = np.zeros((n, P))
    speed = np.zeros((n, P))
    phase = np.zeros((n, P))
    if P == 0:
        return PeopleState(t, xy, heading, speed, phase)

    # Non-overlapping start positions (rejection sampling, 0.9 m apart).
    p = np.zeros((P, 2))
    for i in range(P):
        for _ in range(1000):
            c = rng.uniform(lo_xy, hi_xy)
            if (i == 0 or np.min(np.linalg.norm(p[:i] - c, axis=1)) > 0.9) and \
                    _free_of_boxes(c[None], boxes, OCCLUDER_CLEARANCE_M + 0.1)[0]:
                break
        p[i] = c
    goal = rng.uniform(lo_xy, hi_xy, size=(P, 2)) if len(boxes) == 0 else _sample_free(rng, lo_xy, hi_xy, boxes, P)
    pref = rng.uniform(*cfg.people.speed_range_m_s, size=P)
    pause = np.where(rng.random(P) < 0.3, rng.uniform(*cfg.people.pause_range_s, size=P), 0.0)
    v = np.zeros((P, 2))
    hd = np.arctan2(goal[:, 1] - p[:, 1], goal[:, 0] - p[:, 0])
    ph = rng.uniform(0, 2 * np.pi, size=P)
    tau_s, max_turn_rad_s = 0.5, 2.5
    # Speakers stop to talk: they slow down from STOP_BEFORE_SPEAKING_S before each interval.
    talking = np.zeros((n, P), dtype=bool)
    for spk in cfg.speakers:
        for a, b in spk.intervals_s:
            talking[:, spk.person_id] |= (t >= a - STOP_BEFORE_SPEAKING_S) & (t <= b)
    xy[0], heading[0], phase[0] = p, hd, ph
    for k in range(1, n):
        to_goal = goal - p
        dist = np.linalg.norm(to_goal, axis=1)
        # Slow down when close to the goal, stand still while pausing or talking.
        want = pref * np.clip(dist / 0.8, 0.0, 1.0)
        want[(pause > 0) | talking[k]] = 0.0
        desired = to_goal / np.maximum(dist, 1e-9)[:, None] * want[:, None]
        if len(boxes):
            q, dq = _nearest_on_boxes(p, boxes)
            nrm = (p[:, None, :] - q) / np.maximum(dq, 1e-9)[..., None]  # (P, B, 2) away from each box
            into = np.einsum("pd,pbd->pb", desired, nrm)
            slide = (dq < 0.6) & (into < 0)
            desired = desired - np.einsum("pb,pbd->pd", np.where(slide, into, 0.0), nrm)
            sp_d = np.linalg.norm(desired, axis=1)
            desired *= (want / np.maximum(sp_d, 1e-9))[:, None] * (sp_d > 1e-6)[:, None]
        # Social force between people (exponential repulsion) and from the walls.
        d = p[:, None, :] - p[None, :, :]
        r = np.linalg.norm(d, axis=2) + np.eye(P)
        f = 2.0 * np.exp((0.8 - r) / 0.25) / r
        np.fill_diagonal(f, 0.0)
        rep = np.einsum("ij,ijk->ik", np.where(r < 2.0, f, 0.0), d)
        rep[:, 0] += 1.0 * np.exp((lo_xy[0] - p[:, 0]) / 0.2) - 1.0 * np.exp((p[:, 0] - hi_xy[0]) / 0.2)
        rep[:, 1] += 1.0 * np.exp((lo_xy[1] - p[:, 1]) / 0.2) - 1.0 * np.exp((p[:, 1] - hi_xy[1]) / 0.2)
        if len(boxes):
            rep += np.einsum("pb,pbd->pd", 1.0 * np.exp((OCCLUDER_CLEARANCE_M - dq) / 0.1), nrm)
        rep[talking[k]] *= 0.1  # a talker holds their ground; the others walk around them
        v = v + ((desired - v) / tau_s + rep) * DT_S
        sp = np.linalg.norm(v, axis=1)
        v *= (np.minimum(sp, 1.8) / np.maximum(sp, 1e-9))[:, None]
        p = np.clip(p + v * DT_S, lo_xy - 0.25, hi_xy + 0.25)
        if len(boxes):
            q, dq = _nearest_on_boxes(p, boxes)
            b = np.argmin(dq, axis=1)
            rows = np.arange(P)
            inside = dq[rows, b] < OCCLUDER_CLEARANCE_M
            if inside.any():
                qb, db = q[rows, b][inside], dq[rows, b][inside]
                away = (p[inside] - qb) / np.maximum(db, 1e-9)[:, None]
                p[inside] = qb + away * OCCLUDER_CLEARANCE_M
        sp = np.linalg.norm(v, axis=1)
        # Turn the body towards the walking direction (or the goal when standing) at a bounded rate.
        aim = np.where(sp > 0.15, np.arctan2(v[:, 1], v[:, 0]), np.arctan2(to_goal[:, 1], to_goal[:, 0]))
        hd = hd + np.clip(_wrap(aim - hd), -max_turn_rad_s * DT_S, max_turn_rad_s * DT_S)
        ph = ph + 2 * np.pi * sp * DT_S / STRIDE_M
        pause = np.maximum(pause - DT_S, 0.0)
        reached = (dist < 0.35) & (pause == 0)
        if reached.any():
            stop = reached & (rng.random(P) < cfg.people.pause_probability)
            pause[stop] = rng.uniform(*cfg.people.pause_range_s, size=int(stop.sum()))
            goal[reached] = (rng.uniform(lo_xy, hi_xy, size=(int(reached.sum()), 2)) if len(boxes) == 0
                             else _sample_free(rng, lo_xy, hi_xy, boxes, int(reached.sum())))
        xy[k], heading[k], speed[k], phase[k] = p, hd, sp, ph
    return PeopleState(t, xy, heading, speed, phase)


class Scene:
    """The simulated world: room, people and their motion, who speaks when, and sensor poses.

    Parameters
    ----------
    config : SceneConfig
        The scene description; ``config.seed`` makes everything reproducible.

    Attributes
    ----------
    room_xy_m : tuple of 4 float
        ``(x_min, x_max, y_min, y_max)`` of the room's walls [m].
    wall_height_m : float
    bodies : list of Body
        One per person, ``bodies[i].person_id == i``.
    """

    def __init__(self, config: SceneConfig) -> None:
        self.config = config
        rng = np.random.default_rng([config.seed, 1])
        self.room_xy_m = config.room_xy_m
        self.wall_height_m = float(config.wall_height_m)
        self.bodies = _random_bodies(config, rng)
        #: Static occluders (B, 6): ``[x_min, x_max, y_min, y_max, z_min, z_max]`` [m].
        self.occluder_boxes_m = np.array([o.box_m() for o in config.occluders], dtype=float).reshape(-1, 6)
        self._track = _walk(config, self.bodies, rng)
        self.person_ids = np.arange(len(self.bodies))
        self.height_m = np.array([b.height_m for b in self.bodies])
        # Static shape columns, gathered once for bodies_at (called per frame and per laser scan).
        self._shape = {f: np.array([getattr(b, f) for b in self.bodies], dtype=float) for f in (
            "leg_spacing_m", "leg_radius_m", "hip_height_m", "torso_radius_m", "torso_top_m", "head_center_z_m",
            "head_radius_m")}

    @property
    def n_people(self) -> int:
        return len(self.bodies)

    @property
    def duration_s(self) -> float:
        return float(self.config.duration_s)

    # -- kinematics ---------------------------------------------------------
    def people_at(self, times_s) -> PeopleState:
        """People state at times (T,) [s] (linear interpolation of the walking model, clamped to the duration)."""
        t = np.atleast_1d(np.asarray(times_s, dtype=float))
        if not np.isfinite(t).all():
            raise ValueError("times_s must be finite")
        tr = self._track
        u = np.clip(t / DT_S, 0.0, len(tr.times_s) - 1.000001)
        k = np.floor(u).astype(int)
        w = (u - k)[:, None]

        def lerp(a: np.ndarray) -> np.ndarray:
            return a[k] * (1 - w[..., None] if a.ndim == 3 else 1 - w) + a[k + 1] * (w[..., None] if a.ndim == 3 else w)

        return PeopleState(t, lerp(tr.xy_m), lerp(tr.heading_rad), lerp(tr.speed_m_s), lerp(tr.gait_phase_rad))

    def bodies_at(self, time_s: float):
        """Every body volume at one time.

        Returns
        -------
        cylinders : ndarray, shape (3P, 5), float64
            ``[x_m, y_m, radius_m, z_bottom_m, z_top_m]``: per person the left leg, the right leg, the torso.
        cylinder_person_ids : ndarray, shape (3P,), int
        spheres : ndarray, shape (P, 4), float64
            Heads, ``[x_m, y_m, z_m, radius_m]``.
        sphere_person_ids : ndarray, shape (P,), int
        """
        st = self.people_at([time_s])
        P = self.n_people
        xy = st.xy_m[0]
        hd = st.heading_rad[0]
        fwd = np.stack([np.cos(hd), np.sin(hd)], axis=1)
        left = np.stack([-np.sin(hd), np.cos(hd)], axis=1)
        # Legs swing apart along the heading while walking, together while standing.
        swing = 0.2 * np.clip(st.speed_m_s[0] / 1.2, 0.0, 1.0) * np.sin(st.gait_phase_rad[0])
        sh = self._shape
        cyl = np.zeros((P, 3, 5))
        for j, side in enumerate((1.0, -1.0)):
            cyl[:, j, :2] = xy + left * (side * sh["leg_spacing_m"] / 2)[:, None] + fwd * (side * swing)[:, None]
            cyl[:, j, 2] = sh["leg_radius_m"]
            cyl[:, j, 4] = sh["hip_height_m"]
        cyl[:, 2, :2] = xy
        cyl[:, 2, 2] = sh["torso_radius_m"]
        cyl[:, 2, 3] = sh["hip_height_m"]
        cyl[:, 2, 4] = sh["torso_top_m"]
        sph = np.zeros((P, 4))
        sph[:, :2] = xy
        sph[:, 2] = sh["head_center_z_m"]
        sph[:, 3] = sh["head_radius_m"]
        ids = np.arange(P)
        return cyl.reshape(-1, 5), np.repeat(ids, 3), sph, ids.copy()

    # -- sound ----------------------------------------------------------------
    def T_world_head(self) -> np.ndarray | None:
        """Pose (4, 4) of the binaural head (x forward, y left, z up), or None without a head."""
        return None if self.config.head is None else self.config.head.T_world_head()

    def speaking_at(self, times_s) -> np.ndarray:
        """Boolean (T, P): person p speaks at time t."""
        t = np.atleast_1d(np.asarray(times_s, dtype=float))
        out = np.zeros((t.size, self.n_people), dtype=bool)
        for s in self.config.speakers:
            for a, b in s.intervals_s:
                out[:, s.person_id] |= (t >= a) & (t < b)
        return out

    def mouth_positions_at(self, times_s) -> np.ndarray:
        """Sound-source positions (T, P, 3) [m]: the centre of each person's head sphere."""
        st = self.people_at(times_s)
        z = self._shape["head_center_z_m"]
        return np.concatenate([st.xy_m, np.broadcast_to(z, st.xy_m.shape[:2])[..., None]], axis=-1)

    def azimuth_in_head_at(self, times_s) -> tuple[np.ndarray, np.ndarray]:
        """Azimuth and elevation (T, P) [rad] of every person's mouth in the head frame.

        Azimuth is ``atan2(y_head, x_head)`` (0 straight ahead, positive to the left), elevation
        ``atan2(z_head, hypot(x_head, y_head))``.
        """
        T = self.T_world_head()
        if T is None:
            raise ValueError("the scene has no binaural head (config.head is None)")
        p = self.mouth_positions_at(times_s) - T[:3, 3]
        q = p @ T[:3, :3]
        return np.arctan2(q[..., 1], q[..., 0]), np.arctan2(q[..., 2], np.hypot(q[..., 0], q[..., 1]))


def sample_points_in_bodies(cylinders, spheres, n_per_volume: int, rng: np.random.Generator):
    """Uniform random points inside every body volume (e.g. to check masks or ray casts against).

    Parameters
    ----------
    cylinders : ndarray, shape (C, 5)
        ``[x_m, y_m, radius_m, z_bottom_m, z_top_m]`` as from :meth:`Scene.bodies_at`.
    spheres : ndarray, shape (S, 4)
        ``[x_m, y_m, z_m, radius_m]``.
    n_per_volume : int
    rng : numpy.random.Generator

    Returns
    -------
    points : ndarray, shape ((C + S) * n_per_volume, 3)
        World points [m], the cylinders' first.
    volume_index : ndarray, shape ((C + S) * n_per_volume,) int
        Row of the volume each point is in: ``0..C-1`` cylinders, ``C..C+S-1`` spheres.
    """
    cyl = np.asarray(cylinders, dtype=float).reshape(-1, 5)
    sph = np.asarray(spheres, dtype=float).reshape(-1, 4)
    n = int(n_per_volume)
    a = rng.uniform(0, 2 * np.pi, (len(cyl), n))
    r = cyl[:, 2, None] * np.sqrt(rng.uniform(0, 1, (len(cyl), n)))
    z = cyl[:, 3, None] + (cyl[:, 4] - cyl[:, 3])[:, None] * rng.uniform(0, 1, (len(cyl), n))
    pc = np.stack([cyl[:, 0, None] + r * np.cos(a), cyl[:, 1, None] + r * np.sin(a), z], axis=-1)
    v = rng.normal(size=(len(sph), n, 3))
    v *= (sph[:, 3, None] * np.cbrt(rng.uniform(0, 1, (len(sph), n))))[..., None] / np.linalg.norm(v, axis=-1,
                                                                                                 keepdims=True)
    ps = sph[:, None, :3] + v
    idx = np.repeat(np.arange(len(cyl) + len(sph)), n)
    return np.concatenate([pc.reshape(-1, 3), ps.reshape(-1, 3)]), idx
