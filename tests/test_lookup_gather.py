"""ImagePlaneLookup.gather (numba kernel) against a numpy fancy-indexing reference; dtypes, fill and out buffers."""

from __future__ import annotations

import numpy as np
import pytest

from planefuse.geometry import default_camera_ring
from planefuse.grid import PlaneStack
from planefuse.registration import ImagePlaneLookup


@pytest.fixture(scope="module")
def lut():
    stack = PlaneStack.from_extent([0.0, 0.8, 1.6], (0.0, 10.0), (0.0, 10.0), 0.1)
    return ImagePlaneLookup.from_camera(default_camera_ring()[0], stack)


def reference(lut, image, fill):
    flat = image.astype(float).ravel()
    vis = lut.visible
    out = np.full(lut.pixel_index.shape, fill, dtype=float)
    out[vis] = flat[lut.pixel_index[vis]]
    return out


@pytest.mark.parametrize("img_dtype", [np.uint8, np.float32, np.float64])
def test_gather_matches_fancy_indexing(lut, rng, img_dtype):
    image = (rng.random((288, 360)) * 255).astype(img_dtype)
    got = lut.gather(image)
    assert got.dtype == np.float32 and got.shape == lut.stack.shape
    np.testing.assert_array_equal(got, reference(lut, image, np.nan).astype(np.float32))
    assert 0 < lut.visible.sum() < lut.visible.size  # both branches (seen and unseen cells) are exercised


def test_gather_fill_and_out_buffers(lut, rng):
    image = rng.random((288, 360))
    out64 = np.empty(lut.stack.shape)
    res = lut.gather(image, fill=-1.0, out=out64)
    assert res is out64
    np.testing.assert_array_equal(out64, reference(lut, image, -1.0))
    # A non-contiguous output view is filled too.
    big = np.zeros(lut.stack.shape[:2] + (2 * lut.stack.nx,), np.float32)
    view = big[..., ::2]
    lut.gather(image, fill=0.5, out=view)
    np.testing.assert_array_equal(view, reference(lut, image, 0.5).astype(np.float32))
    with pytest.raises(ValueError, match="out must be a float32/float64 array"):
        lut.gather(image, out=np.empty(lut.stack.shape, np.int32))
    with pytest.raises(ValueError, match="out must be a float32/float64 array"):
        lut.gather(image, out=np.empty((1, 2, 3), np.float32))
