"""The whole system end to end: recording -> every modality on the planes -> BOF -> tracks -> metrics."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .._params import check_fields, require
from .._state import StateDict, get, sub_state, with_prefix
from ..eval import EVAL_WARMUP_S, system_metrics
from ..grid import PlaneStack, cells_filled_by_occluders, check_occluder_boxes
from ..io import Recording
from ..laser import LaserSensorModel
from ..tracking import (AppearanceObserver, AppearanceParams, EvidenceTracker, StitchParams, TrackerOutput,
                        TrackingParams, fill_track_gaps,
                        TrackViews, smooth_track_positions, stitch_tracks)
from ..vision import CameraParams
from ._streams import (EvidenceSource, MergedEvidence, ModalityReport, camera_source, consumed_from_state,
                       laser_sources, sound_sources)

__all__ = ["SystemParams", "SystemResult", "SystemRun", "run_system", "evaluate_system",
           "stack_for_recording", "system_laser_model", "CHECKPOINT_FORMAT", "check_cameras_against_stack",
           "check_memory", "filter_memory_bytes", "available_memory_bytes", "memory_limits_bytes",
           "writer_buffered_steps", "can_evaluate", "EVAL_WARMUP_S", "recording_with_ignore_rects"]

#: Version of :meth:`SystemRun.state_dict`'s layout (a checkpoint of another version is not resumed).
CHECKPOINT_FORMAT = 7  # 2: the BOF's active tiles, the Kalman tracks; 3: each weighted sensor's last message time;
#                       4: the report's laser-point stride; 5: the tracks' supported time; 6: cameras weighted each;
#                       7: the evidence fused since the last output step (cluster positions)


def system_laser_model() -> LaserSensorModel:
    """The laser inverse sensor model the whole system uses by default.

    ``P(occ | return) = 0.9``, ``P(occ | beam crossed) = 0.45``: a person's legs fill a small part of a
    10 cm cell, so a beam passing through a cell says little about it (the laser mapping's own default,
    0.35, frees the cells between and beside the legs at every sweep and no column forms), while a return
    off a leg is precise. Laser-only recall on the demo scene goes from about 0.1 to about 0.7 at
    precision 1.0 (docs/results.md, ``## Whole system (demo scene)``).
    """
    return LaserSensorModel(p_occupied_hit=0.9, p_occupied_free=0.45)


@dataclass(frozen=True)
class SystemParams:
    """What to run: every parameter of the whole system, and the one place their defaults live.

    The run configuration (:class:`planefuse.config.RunConfig`) takes its defaults from here and maps
    each of its fields onto one attribute below (docs/pipeline.md lists the mapping).

    Attributes
    ----------
    heights_m : tuple of float or None
        Plane heights above the ground plane [m] (None: the recording's suggestion).
    cell_size_m : float
        Grid cell side [m].
    x_range_m, y_range_m : (float, float) or None
        World X and Y extent of the grid [m]; None: the recording's room less ``wall_margin_m``.
    wall_margin_m : float
        Margin [m] kept from the room's walls (static, seen by the laser) when the extent comes from
        the recording.
    cameras, laser, sound : bool
        Modalities to fuse.
    use_filter : bool
        False: no temporal filtering (each output step is the current evidence alone,
        the "no filter" ablation): prediction resets the grid to the prior, and no message is weighted
        by a correlation time (below).
    camera_correlation_s, laser_correlation_s, sound_correlation_s : float
        Correlation time ``tau`` [s] >= 0 of the errors of each camera's evidence, of each laser's and
        of each binaural head's: the filter weighs every message by ``min(1, dt / tau)``, ``dt`` the time
        since that sensor's previous message (``TrackingParams.evidence_correlation_s``; 0: every message
        counts fully); each camera by the time since its own previous live frame (per-cell sensor model:
        :func:`planefuse.vision.camera_detections` ``correlation_s``; the generative model's fused message as
        one sensor). A camera's errors (crossing silhouette rays of standing people, single-view rays, a
        camera gone) persist for many frames; the laser's and sound's, at their rates, were not found to.
    occluder_boxes_m : tuple of (x_min, x_max, y_min, y_max, z_min, z_max)
        Known static occluders of the installation (pillars, shelves, counters), axis-aligned boxes in the
        world frame [m] (:mod:`planefuse.grid._occluders`): each camera leaves the cells whose line of sight
        passes through one unobserved (no evidence either way, as an ignored image region), and the cells a
        box fills are free of people whatever the sensors say there (a laser's returns there are off the
        box; :class:`planefuse.tracking.EvidenceTracker` ``static_cells``). Empty: none declared. Only with the
        cameras' per-cell sensor model (``"cell"``).
    camera_ignore_rects_px : tuple of (str, int, int, int, int)
        Image regions that are not scene evidence, on top of the recording's own (``planefuse import
        --ignore-rect``): ``(camera name, u_min, v_min, u_max, v_max)`` [px, max exclusive], as unobserved as the
        recording's (:func:`recording_with_ignore_rects`). Empty: none.
    camera_params : planefuse.vision.CameraParams
        Camera pipeline parameters (foreground, sensor model, person model, registration).
    laser_model : planefuse.laser.LaserSensorModel
        Inverse sensor model of the lasers (:func:`system_laser_model`).
    tracking : TrackingParams
        Filter, clustering and tracker settings.
    sound_block_s : float
        Length of the audio blocks localised one at a time [s].
    sound_model_path : Path or None
        Calibrated binaural sensor model file (None: the spherical-head model).
    output_period_s : float
        Time between output steps [s].
    match_distance_m : float
        Evaluation: largest distance [m] of a detection or track from the person it is matched to.
    appearance : planefuse.tracking.AppearanceParams
        How the tracks' appearance is read from the camera frames (used where the tracker uses appearance,
        ``tracking.tracker.appearance_weight`` or ``reid_max_s``; docs/identities.md).
    stitch : planefuse.tracking.StitchParams
        The offline pass over a finished run's tracks (``stitch.enabled``): tracklets joined across gaps by time,
        space and appearance (:func:`planefuse.tracking.stitch_identities`; docs/identities.md).
    """

    heights_m: tuple[float, ...] | None = (0.1, 0.5, 1.0, 1.5)
    cell_size_m: float = 0.1
    x_range_m: tuple[float, float] | None = None
    y_range_m: tuple[float, float] | None = None
    wall_margin_m: float = 0.2
    cameras: bool = True
    laser: bool = True
    sound: bool = True
    use_filter: bool = True
    camera_correlation_s: float = 0.5
    laser_correlation_s: float = 0.0
    sound_correlation_s: float = 0.0
    occluder_boxes_m: tuple[tuple[float, float, float, float, float, float], ...] = ()
    camera_ignore_rects_px: tuple[tuple[str, int, int, int, int], ...] = ()
    camera_params: CameraParams = field(default_factory=CameraParams)
    laser_model: LaserSensorModel = field(default_factory=system_laser_model)
    tracking: TrackingParams = field(default_factory=TrackingParams)
    sound_block_s: float = 0.5
    sound_model_path: Path | None = None
    output_period_s: float = 0.2
    match_distance_m: float = 0.5
    appearance: AppearanceParams = field(default_factory=AppearanceParams)
    stitch: StitchParams = field(default_factory=StitchParams)

    def __post_init__(self) -> None:
        check_fields(self, cell_size_m=">0", wall_margin_m=">=0", sound_block_s=">0", output_period_s=">0",
                     match_distance_m=">0", camera_correlation_s=">=0", laser_correlation_s=">=0",
                     sound_correlation_s=">=0")
        rects = []
        for r in self.camera_ignore_rects_px:
            ok = len(r) == 5 and isinstance(r[0], str) and all(float(v).is_integer() for v in r[1:])
            require(ok, self, "camera_ignore_rects_px", f"each entry must be (camera, u_min, v_min, u_max, v_max) "
                    f"with integer pixels, got {list(r)}")
            name, u0, v0, u1, v1 = r[0], *(int(v) for v in r[1:])
            require(0 <= u0 < u1 and 0 <= v0 < v1, self, "camera_ignore_rects_px",
                    f"{name}: a rectangle needs 0 <= u_min < u_max and 0 <= v_min < v_max, got {[u0, v0, u1, v1]}")
            rects.append((name, u0, v0, u1, v1))
        object.__setattr__(self, "camera_ignore_rects_px", tuple(rects))
        # metres, not millimetres or centimetres: a cell is at most 5 m, a plane at most 10 m above the ground
        require(self.cell_size_m <= 5.0, self, "cell_size_m", f"must be at most 5 m, got {self.cell_size_m}")
        try:
            boxes = check_occluder_boxes(self.occluder_boxes_m, "boxes")
        except ValueError as err:
            require(False, self, "occluder_boxes_m", str(err))
        object.__setattr__(self, "occluder_boxes_m", tuple(tuple(float(v) for v in b) for b in boxes))
        require(not (len(boxes) and self.cameras and self.camera_params.sensor_model != "cell"), self,
                "occluder_boxes_m", "static occluders are modelled by the cameras' per-cell sensor model only "
                f"(camera_params.sensor_model 'cell'), got {self.camera_params.sensor_model!r}")
        require(self.cameras or self.laser or self.sound, self, "cameras",
                "at least one of cameras, laser, sound must be enabled")
        if self.heights_m is not None:
            h = self.heights_m
            require(len(h) > 0 and all(b > a for a, b in zip(h, h[1:])), self, "heights_m",
                    f"must be at least one height, strictly increasing, got {list(h)}")
            require(all(0.0 <= z <= 10.0 for z in h), self, "heights_m", f"must each be in [0, 10] m, got {list(h)}")
        for name in ("x_range_m", "y_range_m"):
            r = getattr(self, name)
            require(r is None or (len(r) == 2 and r[0] < r[1]), self, name, f"must be (min, max), min < max, got {r}")
        if self.x_range_m is not None and self.y_range_m is not None:
            try:
                PlaneStack.from_extent(self.heights_m or (0.0,), self.x_range_m, self.y_range_m, self.cell_size_m)
            except ValueError as err:
                require(False, self, "cell_size_m", str(err))


@dataclass
class SystemResult:
    """Outputs of :func:`run_system`."""

    stack: PlaneStack
    outputs: list[TrackerOutput]
    report: ModalityReport
    elapsed_s: float
    metrics: dict = field(default_factory=dict)
    #: per track identity, its appearance model in words (:meth:`SystemRun.track_appearance`; empty without)
    track_appearance: dict = field(default_factory=dict)
    #: identity -> the identity it continues after the offline stitching (``SystemParams.stitch``; empty without)
    stitched: dict = field(default_factory=dict)


def stack_for_recording(rec: Recording, params: SystemParams, *, check_cameras: bool = True,
                        buffered_steps: int = 0) -> PlaneStack:
    """The plane stack of ``params`` on ``rec``: the configured extent, or else the recording's monitored
    area ``rec.room_xy_m`` less ``params.wall_margin_m`` on every side, so that the walls (static, seen by
    the laser) are not inside the grid; the configured heights, or else the recording's suggestion.

    Refused (``ValueError``): cameras and planes that cannot work together, occluders far from the grid, and a
    grid whose state and ``buffered_steps`` output grids (:func:`writer_buffered_steps`) do not fit in the
    available memory (:func:`check_memory`)."""
    heights = params.heights_m if params.heights_m is not None else tuple(rec.planes_heights_m)
    x, y = params.x_range_m, params.y_range_m
    if x is None or y is None:
        if rec.room_xy_m is None:
            raise ValueError("the recording has no room_xy_m: give the grid extent (planes.x_range_m, "
                             "planes.y_range_m) explicitly")
        x0, x1, y0, y1 = rec.room_xy_m
        m = params.wall_margin_m
        x = x if x is not None else (x0 + m, x1 - m)
        y = y if y is not None else (y0 + m, y1 - m)
    stack = PlaneStack.from_extent(heights, x, y, params.cell_size_m)
    if params.cameras and check_cameras:
        check_cameras_against_stack(rec.cameras, stack)
    check_occluders_against_stack(params.occluder_boxes_m, stack)
    check_memory(stack, params, n_cameras=len(rec.cameras) if params.cameras else 0, buffered_steps=buffered_steps)
    return stack


def recording_with_ignore_rects(rec: Recording, rects) -> Recording:
    """``rec`` with the image rectangles ``rects`` ((camera, u_min, v_min, u_max, v_max) [px, max exclusive])
    added to its cameras' ignore masks (a copy: ``rec`` and its streams are not changed; ``rec`` itself when
    ``rects`` is empty).

    Raises
    ------
    ValueError
        A camera the recording does not have, or a rectangle reaching past its image.
    """
    if not rects:
        return rec
    import copy

    streams = dict(rec.camera_streams)
    for name, u0, v0, u1, v1 in rects:
        if name not in streams:
            raise ValueError(f"sensors.cameras.ignore_rects_px names camera {name!r}, which the recording does not "
                             f"have (its cameras: {', '.join(rec.camera_streams) or 'none'})")
        cs = streams[name]
        if cs is rec.camera_streams[name]:
            cs = streams[name] = copy.copy(cs)
        w, h = cs.camera.intrinsics.width_px, cs.camera.intrinsics.height_px
        if u1 > w or v1 > h:
            raise ValueError(f"sensors.cameras.ignore_rects_px: rectangle {[u0, v0, u1, v1]} of camera {name!r} "
                             f"reaches past its {w}x{h} px image")
        mask = np.zeros((h, w), bool) if cs.ignore_mask is None else cs.ignore_mask.copy()
        mask[v0:v1, u0:u1] = True
        cs.ignore_mask = mask
    return replace(rec, camera_streams=streams)


def can_evaluate(rec: Recording, times_s) -> bool:
    """True when ``rec`` has people ground truth and an output step at ``times_s`` falls in its evaluated span
    (after the first :data:`EVAL_WARMUP_S`)."""
    if rec.groundtruth is None or rec.groundtruth.people is None or not len(times_s):
        return False
    t = rec.groundtruth.people.times_s
    times_s = np.asarray(times_s, dtype=float)
    return bool(np.any((times_s >= t[0] + EVAL_WARMUP_S) & (times_s <= t[-1] + 1e-9)))


def check_modalities_present(rec: Recording, params: SystemParams) -> None:
    """Raise ``ValueError`` (one line, naming the configuration fields) where ``params`` enables a modality that
    ``rec`` has no stream of: a configured run uses every sensor it asks for, and does not run on without one.
    (:class:`SystemRun` itself fuses the enabled modalities the recording has.)"""
    missing = [field for field, on, streams in (("sensors.cameras.enabled", params.cameras, rec.camera_streams),
                                                ("sensors.laser.enabled", params.laser, rec.lasers),
                                                ("sensors.sound.enabled", params.sound, rec.audio))
               if on and not streams]
    if missing:
        found = [*rec.camera_streams, *rec.lasers, *rec.audio]
        where = rec.root if rec.root is not None else "(in memory)"
        raise ValueError(f"recording {where} has no stream for {', '.join(missing)} (its streams: "
                         f"{', '.join(found) or 'none'}): set {' and '.join(m + ': false' for m in missing)}, or "
                         f"run `planefuse config init --recording DIR` for a configuration fitted to the recording")


#: A camera centre farther than this from the grid (horizontally or in height) [m] is taken for a unit error.
FAR_FROM_GRID_M = 100.0
#: A plane closer than this to a camera's centre height [m] is seen edge-on by it.
EDGE_ON_M = 0.05


def _distance_from_grid_m(stack: PlaneStack, x_m: tuple[float, float], y_m: tuple[float, float],
                         z_m: tuple[float, float]) -> float:
    """How far [m] the box ``x_m`` x ``y_m`` x ``z_m`` (a point where each range is one value) lies from the grid:
    the larger of its horizontal distance from the grid's extent and its largest height above or below 0."""
    x0, x1, y0, y1 = stack.extent_m
    horizontal = np.hypot(max(x0 - x_m[1], 0.0, x_m[0] - x1), max(y0 - y_m[1], 0.0, y_m[0] - y1))
    return float(max(horizontal, abs(z_m[0]), abs(z_m[1])))


def check_occluders_against_stack(boxes_m: Sequence, stack: PlaneStack) -> None:
    """Refuse an occluder box more than :data:`FAR_FROM_GRID_M` from the grid, horizontally or in height (a box
    in millimetres in a metre configuration, typically: it would hide nothing, silently).

    Raises
    ------
    ValueError
        Naming ``scene.occluder_boxes_m``, the box and the grid's extent.
    """
    x0, x1, y0, y1 = stack.extent_m
    for k, (bx0, bx1, by0, by1, bz0, bz1) in enumerate(boxes_m):
        d = _distance_from_grid_m(stack, (bx0, bx1), (by0, by1), (bz0, bz1))
        if d > FAR_FROM_GRID_M:
            raise ValueError(
                f"scene.occluder_boxes_m: box {k} {list(map(float, (bx0, bx1, by0, by1, bz0, bz1)))} is {d:.4g} m from "
                f"the grid x {x0:g}..{x1:g} m, y {y0:g}..{y1:g} m (more than {FAR_FROM_GRID_M:g} m): are its units "
                "millimetres? Occluder boxes are in metres")


def check_cameras_against_stack(cameras: Sequence, stack: PlaneStack, *, above: bool = True) -> None:
    """Refuse camera poses and planes that cannot work together (a unit error, planes no camera looks down at).

    Raises
    ------
    ValueError
        A camera centre more than :data:`FAR_FROM_GRID_M` from the grid (translations in millimetres in a
        metre recording, typically); a plane within :data:`EDGE_ON_M` of a camera's height (seen edge-on:
        its image-plane homography is singular); a plane above every camera (none sees it from above; not
        with ``above=False``: ``planefuse check`` reports a plane above any camera, per camera, with
        :func:`planefuse.io.geometry_findings`). The message names the camera or plane.
    """
    if not cameras:
        return
    x0, x1, y0, y1 = stack.extent_m
    far = []
    for cam in cameras:
        cx, cy, cz = (float(v) for v in cam.center_world)
        if _distance_from_grid_m(stack, (cx, cx), (cy, cy), (cz, cz)) > FAR_FROM_GRID_M:
            far.append(f"{cam.name!r} at ({cx:.4g}, {cy:.4g}, {cz:.4g}) m")
    if far:
        raise ValueError(f"camera {', '.join(far)} is more than {FAR_FROM_GRID_M:g} m from the grid "
                         f"x {x0:g}..{x1:g} m, y {y0:g}..{y1:g} m: are its translations (T_world_cam) in "
                         "millimetres? The recording's unit is the metre")
    heights = {cam.name: float(cam.center_world[2]) for cam in cameras}
    for h in stack.heights_m:
        for name, hc in heights.items():
            if abs(h - hc) < EDGE_ON_M:
                raise ValueError(f"the plane at {h:g} m is at the height of camera {name!r} ({hc:.3g} m), which "
                                 "sees it edge-on: move the plane (planes.heights_m)")
    top = max(heights.values())
    over = [h for h in stack.heights_m if h > top] if above else []
    if over:
        raise ValueError(f"plane(s) at {', '.join(f'{h:g}' for h in over)} m above every camera (highest centre "
                         f"{top:.3g} m): no camera sees them from above; lower them (planes.heights_m)")


def filter_memory_bytes(stack: PlaneStack, params: SystemParams, n_cameras: int = 0, buffered_steps: int = 0) -> int:
    """Estimated memory [bytes] of a run's per-cell state on ``stack``, before allocating it.

    Per cell: the filter state, float32 ``P(occ, v_k)`` for the K velocity hypotheses and ``P(free)``, held
    twice (the state and its update): ``2 (K + 1) 4`` bytes; the outputs (occupancy, mean velocity x and
    y): ``3 x 4`` bytes; each camera's plane lookup (pixel u, v float32 and visibility): ``12`` bytes; and
    ``buffered_steps`` float32 occupancy grids the output writer holds at once (:func:`writer_buffered_steps`:
    a chunk of ``chunk_steps`` steps and its stacked copy): ``4`` bytes each.
    """
    K = params.tracking.bof.n_velocities
    per_cell = 2 * (K + 1) * 4 + 3 * 4 + 12 * int(n_cameras) + 4 * int(buffered_steps)
    return int(stack.n_planes * stack.ny * stack.nx) * per_cell


def writer_buffered_steps(chunk_steps: int, zarr: bool = True, n_steps: int = 0) -> int:
    """Occupancy grids (L, ny, nx) the output writer holds at once: a chunk of ``chunk_steps`` steps before it is
    written and its stacked copy while it is (``2 chunk_steps``); without ``zarr`` on disk every one of the run's
    ``n_steps`` steps is kept in memory too."""
    return 2 * int(chunk_steps) + (0 if zarr else int(n_steps))


def _free_memory_bytes() -> int | None:
    """psutil's ``available``, else ``MemAvailable`` of /proc/meminfo (None where neither can be read)."""
    try:
        import psutil

        return int(psutil.virtual_memory().available)
    except ImportError:
        pass
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _address_space_left_bytes() -> int | None:
    """What the process's ``RLIMIT_AS`` (``ulimit -v``) leaves of its address space (None: no limit, or not
    known)."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft == resource.RLIM_INFINITY or soft < 0:
            return None
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmSize:"):
                return max(0, soft - int(line.split()[1]) * 1024)
        return int(soft)
    except (ImportError, OSError, ValueError, IndexError):
        return None


def _cgroup_memory_left_bytes(proc_cgroup: Path = Path("/proc/self/cgroup"),
                              root: Path = Path("/sys/fs/cgroup")) -> int | None:
    """What the process's cgroup leaves [bytes]: v2 ``memory.max`` less ``memory.current``, the tightest along its
    path from its own group up to ``root``; v1 ``memory/memory.limit_in_bytes`` less ``memory.usage_in_bytes``, its
    group's or else the root's (None: no limit, or not known)."""
    try:
        lines = proc_cgroup.read_text().splitlines()
    except OSError:
        return None
    left = None

    def take(have: int) -> None:
        nonlocal left
        left = max(0, have) if left is None else min(left, max(0, have))

    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        if parts[0] == "0" and parts[1] == "":  # v2: the group and each of its parents
            folder = root / parts[2].lstrip("/")
            for d in (folder, *folder.parents):
                try:
                    limit = (d / "memory.max").read_text().strip()
                    used = int((d / "memory.current").read_text().strip())
                except (OSError, ValueError):
                    limit = None
                if limit not in (None, "max"):
                    take(int(limit) - used)
                if d == root:
                    break
        elif "memory" in parts[1].split(","):  # v1
            for d in (root / "memory" / parts[2].lstrip("/"), root / "memory"):
                try:
                    limit_v1 = int((d / "memory.limit_in_bytes").read_text())
                    used = int((d / "memory.usage_in_bytes").read_text())
                except (OSError, ValueError):
                    continue
                if limit_v1 < 2**60:  # "no limit" is a huge number in v1
                    take(limit_v1 - used)
                break
    return left


def memory_limits_bytes() -> dict[str, int]:
    """What bounds a new allocation [bytes], by source: ``"free memory"`` (the machine's available memory),
    ``"RLIMIT_AS"`` (what the process's address-space limit leaves), ``"cgroup memory.max"`` (what its control
    group leaves); a source that cannot be read or sets no limit is absent."""
    out = {}
    for name, value in (("free memory", _free_memory_bytes()), ("RLIMIT_AS", _address_space_left_bytes()),
                        ("cgroup memory.max", _cgroup_memory_left_bytes())):
        if value is not None:
            out[name] = int(value)
    return out


def available_memory_bytes() -> int:
    """Memory available to a new allocation [bytes]: the smallest of :func:`memory_limits_bytes` (free memory,
    the process's ``RLIMIT_AS`` and its cgroup's ``memory.max``); a very large number where none can be read
    (no refusal then)."""
    return min(memory_limits_bytes().values(), default=2**62)


def check_memory(stack: PlaneStack, params: SystemParams, n_cameras: int = 0, buffered_steps: int = 0) -> None:
    """Refuse a grid whose state and the writer's buffers (:func:`filter_memory_bytes`) would not fit in the
    available memory (:func:`available_memory_bytes`: the smallest of the free memory and the process's limits).

    Raises
    ------
    ValueError
        One line: the estimate, what is available and what to change.
    """
    need, have = filter_memory_bytes(stack, params, n_cameras, buffered_steps), available_memory_bytes()
    if need > 0.8 * have:
        K = params.tracking.bof.n_velocities
        buffers = f" and {buffered_steps} buffered output steps (outputs.chunk_steps)" if buffered_steps else ""
        raise ValueError(f"the grid of {stack.n_planes} planes x {stack.ny} x {stack.nx} cells x {K} velocities"
                         f"{buffers} needs about {need / 2**30:.3g} GiB, more than 80 % of the {have / 2**30:.3g} GiB "
                         "available (the smallest of the free memory and the process's limits, RLIMIT_AS and "
                         "cgroup memory.max): coarsen planes.cell_size_m, shrink planes.x_range_m/y_range_m, reduce "
                         "models.filter.n_velocities_per_axis" + (" or outputs.chunk_steps" if buffered_steps else ""))


class SystemRun:
    """One run of the whole system on a recording, which can be checkpointed and resumed exactly.

    Every enabled modality is an :class:`~planefuse.pipeline.EvidenceSource`; their messages are merged by
    time stamp and pushed, one at a time, into an :class:`~planefuse.tracking.EvidenceTracker` (one BOF per
    plane, clustering, tracker). :meth:`state_dict`, taken while an output is handled, holds all the state
    the rest of the run depends on: the messages each source has given, the held evidence, the filter of
    every plane, the tracks and what the modalities reported so far. ``SystemRun(rec, params,
    checkpoint=state)`` starts every source where that state left it and continues with exactly the outputs
    the uninterrupted run would have given. The only past work a resumed run repeats is updating the
    cameras' background models with the frames already seen (OpenCV cannot save them), which is what makes
    the resumed outputs identical.

    Parameters
    ----------
    rec : Recording
    params : SystemParams
    stack : PlaneStack, optional
        Default: :func:`stack_for_recording`.
    checkpoint : mapping, optional
        A :meth:`state_dict` of a run with the same recording, parameters and stack.
    client : distributed.Client, optional
        Run each camera's front end (decoding, background subtraction) as a stream on this dask cluster's
        workers (:func:`planefuse.batch.remote_foregrounds`; the recording must be a folder they can read).
        The outputs are identical to the run's in one process.
    camera_frames : iterable of (time_s, images), optional
        The cameras' synchronised instants as they arrive (a live run, :mod:`planefuse.live`), instead of the
        recording's frames: ``rec`` then gives the calibrations only
        (:func:`~planefuse.pipeline._arriving.arriving_camera_source`). Not with ``checkpoint`` or ``client``.

    Attributes
    ----------
    report : ModalityReport
        What the modalities produced so far (restored from the checkpoint).
    resumed_at_step : int
        Index of the first output step this object computes (0 on a fresh run).
    """

    def __init__(self, rec: Recording, params: SystemParams = SystemParams(), stack: PlaneStack | None = None,
                 checkpoint: Mapping[str, np.ndarray] | None = None, client=None, camera_frames=None) -> None:
        rec = recording_with_ignore_rects(rec, params.camera_ignore_rects_px)
        if camera_frames is not None and (checkpoint is not None or client is not None):
            raise ValueError("a run fed arriving camera frames is not resumed from a checkpoint nor spread on a "
                             "dask cluster")
        self.rec, self.params, self.client = rec, params, client
        self.camera_frames = camera_frames
        self.stack = stack if stack is not None else stack_for_recording(rec, params)
        self.report = ModalityReport()
        #: the tracks' appearance from the camera frames (None: the tracker does not use appearance)
        self.appearance: AppearanceObserver | None = None
        if params.tracking.tracker.uses_appearance and params.cameras and rec.camera_streams:
            self.appearance = AppearanceObserver(rec.cameras, params.appearance,
                                                 [rec.camera(c.name).ignore_mask for c in rec.cameras],
                                                 occluder_boxes_m=params.occluder_boxes_m)
        consumed: dict[str, int] = {}
        if checkpoint is not None:
            version = int(get(checkpoint, "format", "run"))
            if version != CHECKPOINT_FORMAT:
                raise ValueError(f"checkpoint format {version} is not this version's ({CHECKPOINT_FORMAT})")
            self.report.load_state_dict(sub_state(checkpoint, "report"))
            consumed = consumed_from_state(sub_state(checkpoint, "sources"))
        sources = self._sources(consumed)
        if not sources:
            raise ValueError("no enabled modality has a stream in this recording")
        if checkpoint is not None and set(consumed) != {s.name for s in sources}:
            raise ValueError(f"checkpoint has sources {sorted(consumed)}, this run has "
                             f"{sorted(s.name for s in sources)}")
        self.evidence = MergedEvidence(sources)
        tp = replace(params.tracking, output_period_s=params.output_period_s,
                     evidence_correlation_s={**self._correlation_s(), **params.tracking.evidence_correlation_s})
        if not params.use_filter:
            # "no filter" ablation: the grid forgets everything between fused steps (and nothing is weighted)
            # and the clusters, the modes of the last batch's evidence, are not moved onto the step's evidence
            tp = replace(tp, bof=replace(tp.bof, decay_rate_hz=1e6), evidence_correlation_s={},
                         cluster=replace(tp.cluster, position_from_step_evidence=False))
        static = (cells_filled_by_occluders(self.stack, params.occluder_boxes_m) if params.occluder_boxes_m
                  else None)
        self.tracker = EvidenceTracker(self.stack, tp, static_cells=static)
        self.tracker.tracker.observer = self.appearance
        if self.appearance is not None and params.stitch.enabled and params.stitch.split_window_s is not None:
            s = params.stitch  # what the offline splitting reads; an identity that has ended is reduced at once
            self.tracker.tracker.view_log = TrackViews(split=(s.split_window_s, s.split_min_distance,
                                                              s.split_min_views))
        if checkpoint is not None:
            self.tracker.load_state_dict(sub_state(checkpoint, "tracker"))
        self.resumed_at_step = self.tracker.n_outputs

    def _correlation_s(self) -> dict[str, float]:
        """Error correlation time [s] per sensor name of the recording's evidence weighted by the filter's buffer
        (lasers, heads; the cameras' fused message with the generative sensor model, whose evidence does not
        split by camera: with the per-cell model each camera is weighted in the camera source,
        :meth:`_camera_correlation_s`)."""
        p, rec = self.params, self.rec
        cams = {"cameras": p.camera_correlation_s} if p.camera_params.sensor_model != "cell" else {}
        return {**cams, **{n: p.laser_correlation_s for n in rec.lasers},
                **{n: p.sound_correlation_s for n in rec.audio}}

    def _camera_correlation_s(self) -> float:
        """The cameras' correlation time [s] applied per camera by the camera source (per-cell sensor model, with
        the filter; 0 otherwise)."""
        p = self.params
        return p.camera_correlation_s if p.use_filter and p.camera_params.sensor_model == "cell" else 0.0

    def _track_prior(self) -> bool:
        """Whether the generative camera model takes the tracked people as its prior (with the filter only: the
        "no filter" ablation keeps nothing from one step to the next)."""
        cp = self.params.camera_params
        return self.params.use_filter and cp.sensor_model == "generative" and cp.generative.track_prior_ratio != 1.0

    def _tracked_xy(self, time_s: float) -> np.ndarray:
        """The confirmed tracks predicted to ``time_s`` [s], when the camera source computes that instant."""
        return self.tracker.tracker.predicted_xy(time_s)

    def _sources(self, consumed: Mapping[str, int]) -> list[EvidenceSource]:
        rec, params, stack, report = self.rec, self.params, self.stack, self.report
        out = []
        if params.cameras and rec.camera_streams and self.camera_frames is not None:
            from ._arriving import arriving_camera_source

            out.append(arriving_camera_source(rec, stack, params.camera_params, report, self.camera_frames,
                                              occluder_boxes_m=params.occluder_boxes_m,
                                              correlation_s=self._camera_correlation_s(),
                                              tracked_xy=self._tracked_xy if self._track_prior() else None))
        elif params.cameras and rec.camera_streams:
            out.append(camera_source(rec, stack, params.camera_params, report,
                                     start=consumed.get("cameras", 0), client=self.client,
                                     occluder_boxes_m=params.occluder_boxes_m,
                                     correlation_s=self._camera_correlation_s(),
                                     tracked_xy=self._tracked_xy if self._track_prior() else None,
                                     frame_tap=self.appearance.add_frames if self.appearance is not None else None))
        if params.laser and rec.lasers:
            out += laser_sources(rec, stack, params.laser_model, report, start=consumed)
        if params.sound and rec.audio:
            model = None
            if params.sound_model_path is not None:
                from ..audio import BinauralSensorModel

                model = BinauralSensorModel.load(params.sound_model_path)
            out += sound_sources(rec, stack, report, params.sound_block_s, model, start=consumed)
        return out

    @property
    def n_outputs(self) -> int:
        """Output steps given so far, counted from the start of the recording (the next step's index)."""
        return self.tracker.n_outputs

    def outputs(self) -> Iterator[TrackerOutput]:
        """The remaining output steps, in order."""
        yield from self.tracker.drain()  # batches a checkpoint left ready but unprocessed
        for ev in self.evidence:
            yield from self.tracker.push(ev)
        yield from self.tracker.flush()

    def track_appearance(self) -> dict[str, str]:
        """Per track identity ever confirmed, its appearance model in words, e.g. ``{"3": "c0 (31 views): upper
        blue 62 %, lower black 71 %; c1 ..."}`` (the identity decisions explained); empty without appearance."""
        if self.appearance is None:
            return {}
        names = [c.name for c in self.rec.cameras]
        return {str(i): v for i, v in self.tracker.tracker.appearance_summary(self.params.appearance, names).items()}

    def stitch(self, frames) -> tuple[dict[int, int], list[tuple[float, np.ndarray, np.ndarray]]]:
        """The offline stitching of this run's reported tracks ``frames`` ((time_s, ids, xy_m) per step, in time
        order; ``params.stitch``): where ``split_window_s`` is set, the tracklets first cut where their views'
        colours change (:func:`planefuse.tracking.split_times`, the pieces numbered above every identity), then
        joined by :func:`planefuse.tracking.stitch_identities` with the tracks' appearance models. Returns the joins
        (identity or piece -> the identity it takes) and ``frames`` relabelled (each step's entries in order)."""
        tracker = self.tracker.tracker
        return stitch_tracks(frames, tracker.appearance_by_id, tracker.view_log, self.params.stitch)

    def stitch_outputs(self, outputs: list[TrackerOutput]) -> tuple[dict[int, int], list[TrackerOutput]]:
        """The offline pass over this run's finished ``outputs`` (``params.stitch``; docs/identities.md): the
        identities joined (:meth:`stitch`), then each identity's gaps filled and its positions smoothed where
        ``max_fill_gap_s`` and ``smooth_sigma_s`` are set. Returns the joins (identity -> the identity it takes) and
        the outputs with the tracks changed (the rest as they were)."""
        p = self.params.stitch
        mapping, frames = self.stitch([(o.time_s, o.tracks.ids, o.tracks.xy_m) for o in outputs])
        tracks = [replace(o.tracks, ids=ids) for o, (_, ids, _) in zip(outputs, frames)]
        if p.max_fill_gap_s is not None:  # the gaps within one identity: the person was there, unseen
            tracks = fill_track_gaps(tracks, p.max_fill_gap_s)
        if p.smooth_sigma_s is not None:
            tracks = smooth_track_positions(tracks, p.smooth_sigma_s)
        return mapping, [replace(o, tracks=tr) for o, tr in zip(outputs, tracks)]

    def state_dict(self) -> StateDict:
        """The run's state as arrays (:mod:`planefuse._state`); complete while an output is handled."""
        return {"format": np.asarray(CHECKPOINT_FORMAT),
                **with_prefix("sources", self.evidence.state_dict()),
                **with_prefix("tracker", self.tracker.state_dict()),
                **with_prefix("report", self.report.state_dict())}


def run_system(
    rec: Recording,
    params: SystemParams = SystemParams(),
    stack: PlaneStack | None = None,
    on_output: Callable[[TrackerOutput], None] | None = None,
    client=None,
) -> SystemResult:
    """Register every enabled modality on the planes, filter with one BOF per plane and track people.

    Parameters
    ----------
    rec : Recording
        Simulated (:func:`planefuse.sim.simulate`) or read (:func:`planefuse.io.read_recording`).
    params : SystemParams
    stack : PlaneStack, optional
        Default: :func:`stack_for_recording`.
    on_output : callable, optional
        Called with every :class:`TrackerOutput` (progress, writers).
    client : distributed.Client, optional
        The cameras' front ends as streams on this dask cluster (:class:`SystemRun`); same outputs.

    See Also
    --------
    SystemRun : the same run step by step, with checkpoints (what ``run_to_folder`` resumes from).
    """
    run = SystemRun(rec, params, stack, client=client)
    t0 = time.perf_counter()
    outputs = []
    for out in run.outputs():
        outputs.append(out)
        if on_output is not None:
            on_output(out)
    result = SystemResult(run.stack, outputs, run.report, time.perf_counter() - t0,
                          track_appearance=run.track_appearance())
    if params.stitch.enabled:  # the offline pass: the outputs' track identities joined across gaps
        result.stitched, result.outputs = run.stitch_outputs(outputs)
    return result


def evaluate_system(rec: Recording, result: SystemResult, match_distance_m: float = 0.5) -> dict:
    """The metrics of :func:`planefuse.eval.system_metrics` for the output steps of ``result``."""
    outs = result.outputs
    return system_metrics(rec, np.array([o.time_s for o in outs]), [o.detections.xy_m for o in outs],
                          [(o.time_s, o.tracks.ids, o.tracks.xy_m) for o in outs], result.report,
                          result.elapsed_s, match_distance_m)
