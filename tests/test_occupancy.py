"""Generative multi-view occupancy (planefuse.occupancy): mean-field marginals against the exact posterior, a lone
person found, a ghost between two views explained away, ignored pixels giving no evidence."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planefuse.occupancy import GenerativeParams, MeanFieldSolver, Silhouettes, occupancy_marginals

H, W = 40, 60
EXACT = GenerativeParams(prior=0.05, sigma=0.05, max_iterations=500, damping=0.5, tolerance=1e-12)


def _psi(B, A, Wm):
    """Pseudo-distance of the model, from its definition (module docstring)."""
    return (Wm * (B * (1 - A) + (1 - B) * A)).sum() / max((Wm * A).sum(), 1.0)


def _box_image(box):
    A = np.zeros((H, W))
    x0, y0, x1, y1 = box
    A[y0:y1 + 1, x0:x1 + 1] = 1.0
    return A


@pytest.mark.parametrize("fill", [0.0, 0.3, 0.7, 1.0])
def test_single_location_equals_exact_posterior(fill, rng):
    """One location: the mean-field fixed point is the exact posterior (enumeration of X in {0, 1})."""
    boxes = [(10, 5, 25, 35), (30, 2, 50, 30)]
    B = [(rng.random((H, W)) < 0.05).astype(float) for _ in boxes]
    for b, box in zip(B, boxes):
        inside = _box_image(box) > 0
        b[inside] = (rng.random(inside.sum()) < fill)
    sil = Silhouettes(np.array(boxes, dtype=np.int32)[:, None, :], ((H, W), (H, W)))
    q = occupancy_marginals(B, sil, EXACT).marginals[0]
    ones = np.ones((H, W))
    energy = {x: sum(_psi(b, _box_image(box) * x, ones) for b, box in zip(B, boxes)) / EXACT.sigma for x in (0, 1)}
    p1 = EXACT.prior * np.exp(-energy[1])
    p0 = (1 - EXACT.prior) * np.exp(-energy[0])
    assert q == pytest.approx(min(p1 / (p0 + p1), 1 - 1e-6), abs=1e-6)  # the solver holds q <= 1 - 1e-6


def _two_view_scene():
    """Three locations seen by two cameras: people at 0 and 1; location 2 lies on the line of sight of person 0
    in camera A and of person 1 in camera B, so both its silhouettes are foreground (the classic ghost)."""
    boxes = np.array([
        [[5, 5, 20, 35], [35, 5, 50, 35], [5, 5, 20, 35]],     # camera A: the ghost hides behind person 0
        [[5, 5, 20, 35], [35, 5, 50, 35], [35, 5, 50, 35]],    # camera B: the ghost hides behind person 1
    ], dtype=np.int32)
    fg = []
    for c in range(2):
        img = np.zeros((H, W))
        for k in (0, 1):
            x0, y0, x1, y1 = boxes[c, k]
            img[y0:y1 + 1, x0:x1 + 1] = 1.0
        fg.append(img)
    return Silhouettes(boxes, ((H, W), (H, W))), fg


def test_people_found_and_their_ghost_explained_away():
    sil, fg = _two_view_scene()
    q = occupancy_marginals(fg, sil).marginals
    assert q[0] > 0.95 and q[1] > 0.95
    assert q[2] < 0.05
    # the per-cell (independent) view of the same images: every silhouette of location 2 is fully foreground
    assert all(f[sil.boxes_px[c, 2, 1]:sil.boxes_px[c, 2, 3] + 1, sil.boxes_px[c, 2, 0]:sil.boxes_px[c, 2, 2] + 1]
               .mean() == 1.0 for c, f in enumerate(fg))


def test_lone_person_found_empty_scene_stays_at_prior_level():
    sil, fg = _two_view_scene()
    one = [np.zeros((H, W)), np.zeros((H, W))]
    for c in range(2):
        x0, y0, x1, y1 = sil.boxes_px[c, 1]
        one[c][y0:y1 + 1, x0:x1 + 1] = 1.0
    q = occupancy_marginals(one, sil).marginals
    assert q[1] > 0.95 and q[0] < 0.05
    empty = occupancy_marginals([np.zeros((H, W))] * 2, sil).marginals
    assert (empty <= GenerativeParams().prior + 1e-12).all()


def test_ignored_pixels_give_no_evidence():
    """A location whose silhouettes are all in ignored regions keeps exactly its prior, whatever the pixels say."""
    boxes = np.array([[[10, 5, 25, 35]], [[30, 2, 50, 30]]], dtype=np.int32)
    sil = Silhouettes(boxes, ((H, W), (H, W)))
    observed = [~(_box_image(b[0]) > 0) for b in boxes]
    p = GenerativeParams(prior=0.05, max_iterations=200, damping=0.5, tolerance=1e-14)
    for value in (0.0, 1.0):
        q = occupancy_marginals([np.full((H, W), value)] * 2, sil, p, observed=observed).marginals[0]
        assert q == pytest.approx(p.prior, abs=1e-12)


def test_bad_silhouettes_and_images_are_refused():
    with pytest.raises(ValueError, match="outside the 60x40 image"):
        Silhouettes(np.array([[[0, 0, 60, 10]]], dtype=np.int32), ((H, W),))
    sil, _ = _two_view_scene()
    with pytest.raises(ValueError):
        occupancy_marginals([np.zeros((H, W))], sil)


def _exact_marginals(fg, boxes, params, prior=None):
    """Posterior marginals by enumeration of every configuration X in {0, 1}^K (the model's definition); ``prior``
    (K,): each location's prior (default ``params.prior``)."""
    C, K = boxes.shape[:2]
    prior = np.full(K, params.prior) if prior is None else np.asarray(prior)
    post, Z = np.zeros(K), 0.0
    for bits in range(2 ** K):
        X = np.array([(bits >> k) & 1 for k in range(K)])
        energy = 0.0
        for c in range(C):
            A = np.zeros((H, W))
            for k in np.nonzero(X)[0]:
                A = np.maximum(A, _box_image(boxes[c, k]))
            energy += _psi(fg[c], A, np.ones((H, W))) / params.sigma
        wgt = np.exp(-energy) * np.prod(np.where(X == 1, prior, 1 - prior))
        post += wgt * X
        Z += wgt
    return post / Z


def test_mean_field_against_exact_posterior_by_enumeration(rng):
    """Six overlapping locations, two cameras, noisy foreground (5 % of pixels flipped): where someone is present
    the mean-field marginals are within 0.06 of the exact posterior marginals and decide every location alike."""
    p = GenerativeParams(prior=0.1, sigma=0.05, max_iterations=1000, damping=0.5, tolerance=1e-10)
    K, n_scenes = 6, 0
    while n_scenes < 12:
        boxes = np.zeros((2, K, 4), np.int32)
        for c in range(2):
            for k in range(K):
                w, h = rng.integers(6, 12), rng.integers(15, 25)
                x0, y0 = rng.integers(0, W - w), rng.integers(0, H - h)
                boxes[c, k] = [x0, y0, x0 + w - 1, y0 + h - 1]
        truth = rng.random(K) < 0.3
        if not truth.any():
            continue
        n_scenes += 1
        fg = []
        for c in range(2):
            A = np.zeros((H, W))
            for k in np.nonzero(truth)[0]:
                A = np.maximum(A, _box_image(boxes[c, k]))
            fg.append(np.where(rng.random((H, W)) < 0.05, 1 - A, A))
        q = occupancy_marginals(fg, Silhouettes(boxes, ((H, W), (H, W))), p).marginals
        exact = _exact_marginals(fg, boxes, p)
        assert np.abs(q - exact).max() <= 0.06
        assert ((q > 0.5) == (exact > 0.5)).all()


@pytest.mark.parametrize("prior", [0.002, 0.2, 0.6])
def test_per_location_prior_is_the_locations_prior_and_checked(prior, rng):
    """A location's own prior (what the tracks expect) enters as the model's prior does: one location's marginal is
    the exact posterior (enumeration) under that prior; the same prior everywhere as an array gives the marginals of
    a solver with that scalar prior (to rounding); a prior of the wrong size or outside (0, 1) is refused."""
    boxes = np.array([[[10, 5, 25, 35]], [[30, 2, 50, 30]]], dtype=np.int32)
    sil = Silhouettes(boxes, ((H, W), (H, W)))
    fg = [(rng.random((H, W)) < 0.05).astype(float) for _ in range(2)]
    for b, box in zip(fg, boxes[:, 0]):
        inside = _box_image(box) > 0
        b[inside] = rng.random(inside.sum()) < 0.5
    q = MeanFieldSolver(sil, EXACT).solve(fg, prior=[prior]).marginals
    assert q[0] == pytest.approx(min(_exact_marginals(fg, boxes, EXACT, [prior])[0], 1 - 1e-6), abs=1e-6)
    boxes6 = np.repeat(boxes, 3, axis=1) + np.arange(3)[None, :, None] * np.array([1, 0, 1, 0])  # 3 locations
    sil6 = Silhouettes(boxes6.astype(np.int32), ((H, W), (H, W)))
    np.testing.assert_allclose(MeanFieldSolver(sil6, EXACT).solve(fg, prior=np.full(3, prior)).marginals,
                               MeanFieldSolver(sil6, replace(EXACT, prior=prior)).solve(fg).marginals, rtol=1e-12)
    for bad in (np.full(2, 0.1), np.full(3, 0.0), np.full(3, 1.0), np.full(3, np.nan)):
        with pytest.raises(ValueError, match="prior"):
            MeanFieldSolver(sil6, EXACT).solve(fg, prior=bad)


def test_prior_decides_between_locations_the_images_cannot_tell_apart():
    """Two locations on one line of sight of the only camera (the same box): the image says someone is there, not
    which; with equal priors both get the same marginal, with a higher prior on one (a tracked person) that one
    takes the person."""
    boxes = np.array([[[10, 5, 25, 35], [10, 5, 25, 35]]], dtype=np.int32)
    fg = [_box_image(boxes[0, 0])]
    solver = MeanFieldSolver(Silhouettes(boxes, ((H, W),)), GenerativeParams(prior=0.01, sigma=0.05))
    q = solver.solve(fg).marginals
    assert q[0] == q[1]
    q = solver.solve(fg, prior=[0.01, 0.04]).marginals
    assert q[1] > 0.5 > q[0]


def _random_scene(rng, n_cameras: int, n_locations: int, n_unseen: int, n_people: int):
    """Random boxes (C, K, 4) [px] (camera 1 sees not the first ``n_unseen`` locations) and foregrounds: the
    boxes of ``n_people`` random locations filled, 3 % of the pixels on at random."""
    C, K = n_cameras, n_locations
    x0 = rng.integers(0, W - 12, (C, K))
    y0 = rng.integers(0, H - 20, (C, K))
    boxes = np.stack([x0, y0, x0 + rng.integers(3, 12, (C, K)), y0 + rng.integers(8, 20, (C, K))], -1)
    boxes[1, :n_unseen] = -1
    people = rng.choice(K, n_people, replace=False)
    fg = []
    for c in range(C):
        img = (rng.random((H, W)) < 0.03).astype(float)
        for k in people:
            if boxes[c, k, 0] >= 0:
                a, b, e, d = boxes[c, k]
                img[b:d + 1, a:e + 1] = 1.0
        fg.append(img)
    return boxes, fg


def test_threads_give_the_same_marginals(rng):
    """The parallel kernel (cameras on numba's threads) gives the serial kernel's marginals bit for bit."""
    boxes, fg = _random_scene(rng, 4, 300, n_unseen=40, n_people=4)
    sil = Silhouettes(boxes.astype(np.int32), ((H, W),) * 4)
    serial = MeanFieldSolver(sil, GenerativeParams(), threads=1).solve(fg)
    parallel = MeanFieldSolver(sil, GenerativeParams(), threads=2).solve(fg)
    assert np.array_equal(serial.marginals, parallel.marginals)
    assert serial.n_iterations == parallel.n_iterations and serial.n_iterations > 1
    with pytest.raises(ValueError, match="threads must be an integer >= 1"):
        MeanFieldSolver(sil, threads=0)


def test_box_corners_index_the_region_integral_image(rng):
    """The corner positions the kernel keeps per region: read in the integral image of a region (stored at the
    camera's offset), every visible box's four corners give its sum over an image that is 0 outside the region,
    boxes reaching out of the region included (their corners are clamped into it); unseen boxes have none."""
    from planefuse.occupancy._meanfield import _corner_indices

    boxes = np.full((2, 60, 4), -1, np.int64)
    x0, y0 = rng.integers(0, W - 10, 60), rng.integers(0, H - 10, 60)
    boxes[1] = np.stack([x0, y0, x0 + rng.integers(0, 10, 60), y0 + rng.integers(0, 10, 60)], -1)
    boxes[1, ::7] = -1
    o = 123
    corners = np.zeros((2, 60, 4), np.int64)
    for X0, Y0, X1, Y1 in [(0, 0, W - 1, H - 1), (7, 4, 41, 30)]:
        _corner_indices(1, boxes, o, X0, Y0, X1, Y1, corners)
        img = np.zeros((H, W))
        img[Y0:Y1 + 1, X0:X1 + 1] = rng.random((Y1 - Y0 + 1, X1 - X0 + 1))
        store = np.zeros(o + (H + 1) * (W + 1))
        ii = np.zeros((Y1 - Y0 + 2, X1 - X0 + 2))
        ii[1:, 1:] = img[Y0:Y1 + 1, X0:X1 + 1].cumsum(0).cumsum(1)
        store[o:o + ii.size] = ii.ravel()
        for k in range(60):
            if boxes[1, k, 0] < 0:
                assert corners[1, k, 0] == -1
                continue
            i00, i01, i10, i11 = corners[1, k]
            a, b, e, d = boxes[1, k]
            assert store[i11] - store[i01] - store[i10] + store[i00] == pytest.approx(img[b:d + 1, a:e + 1].sum())


def test_marginals_do_not_depend_on_a_background_margin():
    """Pixels that are background and outside every silhouette carry no evidence (``A = B = 0`` there): the ghost
    scene shifted into a larger image (its region no longer at the image origin) gives the same marginals."""
    sil, fg = _two_view_scene()
    dy, dx = 7, 25
    big_boxes = sil.boxes_px + np.array([dx, dy, dx, dy], np.int32)
    big_fg = [np.pad(f, ((dy, 11), (dx, 3))) for f in fg]
    big = Silhouettes(big_boxes, (big_fg[0].shape,) * 2)
    a = occupancy_marginals(fg, sil).marginals
    b = occupancy_marginals(big_fg, big).marginals
    assert np.allclose(a, b, rtol=0, atol=1e-9)
    assert a[0] > 0.9 and a[1] > 0.9 and a[2] < 0.1


def _plain_iteration(fg, boxes, p):
    """The solver's iteration written pixel by pixel from the module docstring (synthetic images as arrays, no
    integral image, difference array, region or location lists), with its documented schedule: damping, dormant
    locations (target < 1e-8) damped without evaluation and refreshed every 5th iteration, locations below
    max(ignored_below, 1e-3 prior) left out of Abar, convergence confirmed on a full iteration."""
    C, K = boxes.shape[:2]
    q = np.full(K, p.prior)
    cut = max(p.ignored_below, 1e-3 * p.prior)
    lpr = np.log((1 - p.prior) / p.prior)
    skip = np.zeros(K, bool)
    full, it = True, 0
    while it < p.max_iterations:
        it += 1
        if it % 5 == 0 or it == p.max_iterations:
            full = True
        if full:
            skip[:] = False
        s = np.zeros(K)
        for c in range(C):
            prod = np.ones((H, W))
            for k in range(K):
                if boxes[c, k, 0] >= 0 and q[k] >= cut:
                    prod *= 1 - q[k] * _box_image(boxes[c, k])
            abar = 1 - prod
            for k in range(K):
                if boxes[c, k, 0] < 0 or skip[k]:
                    continue
                inside = _box_image(boxes[c, k]) > 0
                a1, a0 = abar.copy(), abar.copy()
                a1[inside] = 1.0
                if q[k] >= cut:
                    a0[inside] = np.maximum(1 - (1 - abar[inside]) / (1 - q[k]), 0.0)
                psi = [(fg[c] * (1 - a) + (1 - fg[c]) * a).sum() / max(a.sum(), 1.0) for a in (a1, a0)]
                s[k] += (psi[0] - psi[1]) / p.sigma
        e = np.minimum(lpr + s, 700.0)
        target = np.where(skip, 0.0, 1 / (1 + np.exp(e)))
        qn = np.where(skip, p.damping * q, np.minimum(p.damping * q + (1 - p.damping) * target, 1 - 1e-6))
        moved = (~skip & (np.abs(qn - q) > p.tolerance * np.maximum(q, p.prior))).any()
        skip |= ~skip & (e > 18.42)
        q = qn
        if not moved:
            if full:
                return q, it, True
            full = True
        else:
            full = False
    return q, it, False


@pytest.mark.parametrize("ignored_below", [0.0, 0.02])
def test_solver_equals_a_plain_pixel_by_pixel_iteration(rng, ignored_below):
    """The kernel's economies (integral images, difference array reset by the pass, region rescanned only when the
    set of locations in the synthetic image changes, loops over the active and evaluated locations only) give the
    plain iteration's marginals and iteration count, to the rounding of its different order of sums, on scenes
    where locations turn dormant, drop out of the synthetic image and shrink its region."""
    C, K = 2, 40
    p = GenerativeParams(prior=0.02, ignored_below=ignored_below)
    for _ in range(3):
        boxes, fg = _random_scene(rng, C, K, n_unseen=5, n_people=3)
        res = MeanFieldSolver(Silhouettes(boxes.astype(np.int32), ((H, W),) * C), p).solve(fg)
        q, n_it, converged = _plain_iteration(fg, boxes, p)
        assert res.n_iterations == n_it and res.converged == converged
        assert np.allclose(res.marginals, q, rtol=1e-9, atol=1e-12)
        assert (q > 0.5).sum() >= 2 and (q < 1e-3 * p.prior).any()  # people found, locations left out of Abar


def test_all_observed_mask_gives_the_marginals_of_no_mask(rng):
    """``observed`` all True runs the weighted pass (W read and multiplied), ``observed=None`` the unweighted one
    (W not read): multiplying by 1.0 is exact, so the marginals are the same bits."""
    sil, fg = _two_view_scene()
    fg = [np.clip(f + (rng.random(f.shape) < 0.05), 0, 1) for f in fg]
    a = occupancy_marginals(fg, sil).marginals
    b = occupancy_marginals(fg, sil, observed=[np.ones((H, W), bool)] * 2).marginals
    c = occupancy_marginals(fg, sil, observed=[None, np.ones((H, W), bool)]).marginals
    assert np.array_equal(a, b) and np.array_equal(a, c)
