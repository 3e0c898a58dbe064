"""The generative camera sensor model on the plane stack (planefuse.vision.GenerativeCameraSensor): two cameras,
people rendered as ray-cast cylinders (independent of the silhouette boxes); people found, the per-cell model's
ghost at the crossing of their lines of sight suppressed, evidence in the BOF's form, pipeline selection."""

from __future__ import annotations

import numpy as np
import pytest
from _cylinders import render_cylinder_mask

from planefuse.geometry import default_camera_ring
from planefuse.grid import PlaneStack
from planefuse.vision import (
    CameraParams,
    GenerativeCameraSensor,
    GenerativeSensorParams,
    camera_detections,
    lookups_from_cameras,
)

STACK = PlaneStack.from_extent([0.1, 0.9, 1.6], (0, 10), (0, 10), 0.1)


def _ghost_scene():
    """Cameras in two adjacent corners of the room and two people; the ghost is where the ray from camera 0
    through person A meets the ray from camera 1 through person B (beyond both people, inside the room)."""
    cams = [default_camera_ring(4)[i] for i in (0, 1)]
    people = np.array([[4.0, 3.5], [6.5, 4.0]])
    c0, c1 = cams[0].center_world[:2], cams[1].center_world[:2]
    d0, d1 = people[0] - c0, people[1] - c1
    t = np.linalg.solve(np.stack([d0, -d1], 1), c1 - c0)
    ghost = c0 + t[0] * d0
    frames = [render_cylinder_mask(c, people, 1.75, radius_m=0.22).astype(float) for c in cams]
    return cams, people, ghost, frames


def test_scene_has_a_ghost_for_the_per_cell_model():
    cams, people, ghost, frames = _ghost_scene()
    assert 0 < ghost[0] < 10 and 0 < ghost[1] < 10 and np.linalg.norm(people - ghost, axis=1).min() > 1.0
    lookups = lookups_from_cameras(cams, STACK)
    (_, det), = camera_detections([(0.0, frames)], lookups, STACK, CameraParams(foreground=None))
    assert np.linalg.norm(det.xy_m - ghost, axis=1).min() < 0.4   # the column model reports the ghost


def test_generative_finds_the_people_and_not_their_ghost():
    cams, people, ghost, frames = _ghost_scene()
    sensor = GenerativeCameraSensor(cams, STACK, GenerativeSensorParams(height_range_m=(0.0, 1.75),
                                                                        radius_m=0.22))
    q = sensor.marginals(frames)
    det = sensor.detections(q, 0.0, nms_radius_m=0.45)
    assert len(det.xy_m) == 2
    d = np.linalg.norm(det.xy_m[:, None] - people[None], axis=2)
    assert d.min(axis=0).max() < 0.2
    ev = sensor.log_odds_from_marginals(q)
    iy, ix = STACK.index_from_xy(np.vstack([people, ghost]))
    assert (ev[:, iy[:2], ix[:2]] > 2.0).all()        # strong evidence for the people on every plane
    assert (ev[:, iy[2], ix[2]] < 0.0).all()          # the ghost's cell is evidence of free space
    assert ev.dtype == np.float32 and ev.shape == STACK.shape


def test_missing_camera_gives_no_evidence_and_unseen_cells_are_unknown():
    cams, people, _, frames = _ghost_scene()
    sensor = GenerativeCameraSensor(cams, STACK)
    # with no frame at all every marginal stays at the prior: the evidence is 0 everywhere
    ev = sensor.log_odds_from_marginals(sensor.marginals([None, None]))
    assert np.abs(ev).max() < 1e-3
    seen = sensor.silhouettes.visible.any(0).reshape(STACK.ny, STACK.nx)
    ev = sensor.log_odds_from_marginals(sensor.marginals(frames))
    assert (ev[:, ~seen] == 0).all()


def test_hidden_unknown_leaves_cells_at_the_prior_unknown_and_keeps_the_rest():
    """With an evidence reference above the model's prior, marginals left at the prior (what a person hidden
    behind others in every view gets: his silhouettes change no synthetic image) are evidence against a body at
    every frame; ``hidden_unknown`` makes them unknown, and leaves evidence for the people (above the band) and
    against the ghost (below it) as the two references give them."""
    cams, people, ghost, frames = _ghost_scene()
    kw = dict(height_range_m=(0.0, 1.75), radius_m=0.22, evidence_prior=0.08)
    plain = GenerativeCameraSensor(cams, STACK, GenerativeSensorParams(**kw))
    hidden = GenerativeCameraSensor(cams, STACK, GenerativeSensorParams(**kw, hidden_unknown=True))
    model = GenerativeCameraSensor(cams, STACK, GenerativeSensorParams(**{**kw, "evidence_prior": None}))
    seen = plain.silhouettes.visible.any(0).reshape(STACK.ny, STACK.nx)
    q0 = plain.marginals([None, None])                       # no image: every marginal at the prior
    assert np.allclose(q0, plain.solver_params.prior)
    eps = plain.solver_params.prior
    n_disc = int((np.hypot(*np.mgrid[-2:3, -2:3]) <= 0.22 / STACK.cell_size_m).sum())
    p0 = 1.0 - (1.0 - eps) ** n_disc                          # an interior cell's prior P_0
    expected = np.log(p0 / (1 - p0)) - np.log(0.08 / 0.92)   # about -2.5 per frame, though nothing was seen
    ev = plain.log_odds_from_marginals(q0)
    assert ev[0, 50, 50] == pytest.approx(expected, abs=1e-4) and expected < -2.0
    assert np.abs(hidden.log_odds_from_marginals(q0)).max() < 1e-6
    q = plain.marginals(frames)
    ev_plain, ev_hidden, ev_model = (s.log_odds_from_marginals(q) for s in (plain, hidden, model))
    iy, ix = STACK.index_from_xy(np.vstack([people, ghost]))
    assert (ev_hidden[:, iy[:2], ix[:2]] == ev_plain[:, iy[:2], ix[:2]]).all()   # people: against p_e
    assert (ev_hidden[:, iy[:2], ix[:2]] > 2.0).all()
    assert (ev_hidden[:, iy[2], ix[2]] == ev_model[:, iy[2], ix[2]]).all()      # ghost: against P_0
    assert (ev_hidden[:, iy[2], ix[2]] < 0.0).all()
    assert (ev_hidden[:, ~seen] == 0).all()
    # weak support, between the references: for a body against P_0, against one against p_e; hidden_unknown: none
    qw = q0.copy()
    qw[48:53, 48:53] = 0.002
    ev_plain, ev_hidden, ev_model = (s.log_odds_from_marginals(qw)[0, 50, 50] for s in (plain, hidden, model))
    assert ev_model > 0.5 and ev_plain < -0.5 and ev_hidden == 0.0


def test_pipeline_selects_the_generative_model():
    cams, people, _, frames = _ghost_scene()
    lookups = lookups_from_cameras(cams, STACK)
    params = CameraParams(foreground=None, sensor_model="generative")
    with pytest.raises(ValueError, match="needs the calibrated cameras"):
        next(camera_detections([(0.0, frames)], lookups, STACK, params))
    out = list(camera_detections([(0.0, frames), (0.04, frames)], lookups, STACK, params, cameras=cams))
    assert len(out) == 2
    ev, det = out[1]
    assert ev.sensor == "cameras" and ev.time_s == 0.04 and len(det.xy_m) == 2
    with pytest.raises(ValueError, match="sensor_model"):
        CameraParams(sensor_model="column")


def test_config_selects_the_generative_model_in_the_camera_source(tmp_path):
    """sensors.cameras.sensor_model: generative reaches the camera source of a run: its evidence comes from the
    generative model (people found on a simulated recording, evidence bounded by max_log_odds)."""
    from planefuse.config import load_config
    from planefuse.io import read_recording
    from planefuse.pipeline import stack_for_recording
    from planefuse.pipeline._streams import ModalityReport, camera_source
    from planefuse.sim import default_scene_config, simulate

    simulate(default_scene_config(duration_s=0.4, seed=1)).write(tmp_path / "rec", masks=False)
    (tmp_path / "run.yaml").write_text("recording: rec\nplanes:\n  cell_size_m: 0.2\nsensors:\n  cameras:\n"
                                       "    sensor_model: generative\n")
    cfg = load_config(tmp_path / "run.yaml")
    system = cfg.system_params()
    params = system.camera_params
    assert params.sensor_model == "generative"
    report = ModalityReport()
    rec = read_recording(tmp_path / "rec")
    source = camera_source(rec, stack_for_recording(rec, system), params, report)
    evs = list(source.evidence())
    assert len(evs) == 2 and all(e.sensor == "cameras" for e in evs)  # 0.4 s, cameras at the default 5 Hz
    assert max(float(np.abs(e.log_odds).max()) for e in evs) <= params.generative.max_log_odds + 1e-6
    assert len(report.camera_detections) == 2
    # the generative evidence is the same on every plane of the person's cylinder (the per-cell model's is not)
    assert all(np.array_equal(e.log_odds[0], e.log_odds[-1]) for e in evs)
    assert any(np.abs(e.log_odds).max() > 1.0 for e in evs)


def test_max_iterations_bounds_the_solver_and_is_checked():
    """``max_iterations`` reaches the mean-field solver (its cost on real images, where the relative tolerance
    rarely stops it earlier); below 1 or not an integer it is refused, naming the field."""
    stack = PlaneStack((0.0, 1.0), 0.0, 0.0, 0.25, 8, 8)
    assert GenerativeSensorParams().solver_params(stack).max_iterations == 100
    assert GenerativeSensorParams(max_iterations=7).solver_params(stack).max_iterations == 7
    for bad in (0, 2.5):
        with pytest.raises(ValueError, match=r"GenerativeSensorParams\.max_iterations must be an integer >= 1"):
            GenerativeSensorParams(max_iterations=bad)


def test_tracked_people_prior_raises_their_locations_and_is_not_counted_twice():
    """``location_prior``: ``eps * track_prior_ratio`` within ``track_prior_radius_m`` of a tracked person, ``eps``
    elsewhere, None with ratio 1 or no one tracked. Where the images say nothing (no frame) the marginals stay at
    that prior and the evidence is exactly the uniform prior's (the prior's own share is taken out: the filter
    holds the tracks already); with the images the people are still found and the ghost is still free space."""
    cams, people, ghost, frames = _ghost_scene()
    kw = dict(height_range_m=(0.0, 1.75), radius_m=0.22, evidence_prior=0.08)
    plain = GenerativeCameraSensor(cams, STACK, GenerativeSensorParams(**kw))
    tracked = GenerativeCameraSensor(cams, STACK, GenerativeSensorParams(**kw, track_prior_ratio=3.0,
                                                                         track_prior_radius_m=0.5))
    eps = plain.solver_params.prior
    assert plain.location_prior(people) is None and tracked.location_prior(np.zeros((0, 2))) is None
    prior = tracked.location_prior(people)
    d = np.linalg.norm(STACK.cell_centers_xy()[:, :, None] - people[None, None], axis=-1).min(-1)
    np.testing.assert_array_equal(prior, np.where(d <= 0.5, 3 * eps, eps))
    with pytest.raises(ValueError, match="xy_m"):
        tracked.location_prior([[np.nan, 1.0]])
    q0 = tracked.marginals([None, None], prior)
    np.testing.assert_allclose(q0, prior)
    np.testing.assert_allclose(tracked.log_odds_from_marginals(q0, prior),
                               plain.log_odds_from_marginals(plain.marginals([None, None])), atol=1e-5)
    q = tracked.marginals(frames, prior)
    det = tracked.detections(q, 0.0, nms_radius_m=0.45)
    assert len(det.xy_m) == 2 and np.linalg.norm(det.xy_m[:, None] - people[None], axis=2).min(0).max() < 0.2
    ev = tracked.log_odds_from_marginals(q, prior)
    iy, ix = STACK.index_from_xy(np.vstack([people, ghost]))
    assert (ev[:, iy[:2], ix[:2]] > 2.0).all() and (ev[:, iy[2], ix[2]] < 0.0).all()


def test_track_prior_parameters_are_checked():
    stack = PlaneStack((0.0, 1.0), 0.0, 0.0, 0.1, 8, 8)
    for bad in (0.5, np.nan, np.inf):
        with pytest.raises(ValueError, match=r"track_prior_ratio must be finite and >= 1"):
            GenerativeSensorParams(track_prior_ratio=bad)
    for bad in (0.0, -1.0, np.nan):
        with pytest.raises(ValueError, match=r"track_prior_radius_m must be finite and > 0"):
            GenerativeSensorParams(track_prior_radius_m=bad)
    with pytest.raises(ValueError, match="track_prior_ratio 2000"):
        GenerativeSensorParams(track_prior_ratio=2000.0).solver_params(stack)


def test_camera_pipeline_asks_for_the_tracked_people_at_each_instant():
    """``camera_detections(tracked_xy=...)``: asked with each instant's time, its people become the generative
    model's prior (a ratio of 1 never asks)."""
    cams, people, _, frames = _ghost_scene()
    lookups = lookups_from_cameras(cams, STACK)
    asked = []

    def tracked_xy(t):
        asked.append(t)
        return people

    gen = GenerativeSensorParams(height_range_m=(0.0, 1.75), radius_m=0.22, evidence_prior=0.08)
    for ratio, want in ((1.0, []), (4.0, [0.0, 0.2])):
        params = CameraParams(foreground=None, sensor_model="generative",
                              generative=GenerativeSensorParams(**{**gen.__dict__, "track_prior_ratio": ratio}))
        asked.clear()
        out = list(camera_detections([(0.0, frames), (0.2, frames)], lookups, STACK, params, cameras=cams,
                                     tracked_xy=tracked_xy))
        assert asked == want and len(out) == 2
