"""Shared fixtures: seeded RNG, real-data location, random cameras, a small simulated recording.

Real data: every test that reads ``../shared/data`` goes through :func:`shared_data`, which fails a test not
marked ``realdata`` (so ``-m "not realdata"`` really excludes real data) and skips with a reason where the
data are absent -- unless ``PLANEFUSE_REQUIRE_SHARED_DATA=1`` (set by ``.ci/run`` on CI), where absence is a
failure: a CI machine without ``../shared`` must not turn the real-data tests into quiet skips.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
REQUIRE_ENV = "PLANEFUSE_REQUIRE_SHARED_DATA"

_current_item: pytest.Item | None = None


def pytest_runtest_setup(item: pytest.Item) -> None:
    # before any fixture of the test (module-scoped ones included) is set up
    global _current_item
    _current_item = item


def pytest_runtest_teardown(item: pytest.Item) -> None:
    global _current_item
    _current_item = None


def shared_data(name: str) -> Path:
    """Path of ``../shared/data/<name>`` for a test marked ``realdata``; skip with a reason where absent
    (fail instead when ``PLANEFUSE_REQUIRE_SHARED_DATA=1``)."""
    item = _current_item
    if item is not None and item.get_closest_marker("realdata") is None:
        pytest.fail(f"{item.nodeid} reads ../shared/data/{name} but is not marked @pytest.mark.realdata",
                    pytrace=False)
    p = SHARED_DATA / name
    if not p.exists():
        msg = f"real data {p} is absent (../shared/data not beside the checkout)"
        if os.environ.get(REQUIRE_ENV) == "1":
            pytest.fail(f"{msg}; {REQUIRE_ENV}=1 requires it", pytrace=False)
        pytest.skip(msg)
    return p


def shared_model(name: str) -> Path:
    """Path of ``../shared/models/<name>`` (a pretrained model for tests only), as :func:`shared_data` finds
    ``../shared/data``: the test must be marked ``realdata``; skip with a reason where absent."""
    return shared_data(f"../models/{name}")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(0)


def edit_laser_npz(rec: Path, edit) -> Path:
    """Rewrite the first laser chunk (NPZ) of the recording folder ``rec`` after ``edit(arrays)`` changed its
    dict of arrays in place; returns the chunk's path (hostile-input tests)."""
    p = next((rec / "laser").rglob("*.npz"))
    with np.load(p) as z:
        arrays = {k: z[k] for k in z.files}
    edit(arrays)
    np.savez(p, **arrays)
    return p


@pytest.fixture(scope="module")
def recording_dir(tmp_path_factory) -> Path:
    """A 1 s simulated recording (the default scene, seed 2, JPEG frames), once per module; a module that needs
    another defines its own ``recording_dir``."""
    from planefuse.sim import default_scene_config, simulate

    d = tmp_path_factory.mktemp("rec") / "scene"
    simulate(default_scene_config(duration_s=1.0, seed=2)).write(d, image_format="jpg")
    return d


@pytest.fixture
def rec_copy(recording_dir, tmp_path) -> Path:
    """A copy of ``recording_dir`` the test may damage."""
    d = tmp_path / "rec"
    shutil.copytree(recording_dir, d)
    return d
