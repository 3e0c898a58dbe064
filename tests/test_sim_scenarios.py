"""The named scenario suite: every scenario loads, seeds and durations apply, occluders reach the laser."""

from __future__ import annotations

import numpy as np
import pytest

from planefuse.sim import SCENARIOS, scenario_config, scenario_description


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_every_scenario_loads_with_its_seed_and_duration(name):
    cfg = scenario_config(name, seed=7, duration_s=3.0)
    assert cfg.seed == 7 and cfg.duration_s == pytest.approx(3.0)
    assert scenario_description(name)


def test_unknown_scenario_names_the_known_ones():
    with pytest.raises(ValueError, match="occluders"):
        scenario_config("no-such-scenario", seed=1, duration_s=1.0)


def test_occluders_block_laser_beams():
    from planefuse.laser import HIT_BOX, raycast

    box = np.array([[2.0, 3.0, -0.5, 0.5, 0.0, 2.0]])  # x 2..3 m, y -0.5..0.5 m, 2 m high
    origin = np.zeros((1, 3)) + [0.0, 0.0, 1.0]
    r, kind, _ = raycast(origin, np.array([[1.0, 0.0, 0.0]]), None, None, (-10, 10, -10, 10), 3.0, 30.0,
                         boxes=box, return_hits=True)
    assert kind[0] == HIT_BOX and r[0] == pytest.approx(2.0)
