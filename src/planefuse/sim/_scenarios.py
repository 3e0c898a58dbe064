"""The named scenario suite: scenes that test a temporal filter, each a few lines of scene YAML.

The files live in ``planefuse/data/scenarios/<name>.yaml`` (a :class:`SceneConfig` without ``seed`` and
``duration_s``, which the evaluation sets); their leading comment is their description.

========================  ==========================================================================
``baseline``              the default scene: every camera sees everyone at 25 Hz
``occluders``             two pillars, a shelf and a counter hide people and stop laser beams
``camera_dropout``        one camera black for 2.5 s, one frozen for 2.5 s, 5 % of frames dropped
``low_rate``              the cameras at 5 Hz
``crowd``                 16 people in the room
``outside_cameras``       two cameras see the western part only; the others are laser (and sound) only
========================  ==========================================================================
"""

from __future__ import annotations

from importlib import resources

import yaml

from ._config import SceneConfig

__all__ = ["SCENARIOS", "scenario_config", "scenario_description"]

#: Names of the scenarios, in the order of the result tables.
SCENARIOS = ("baseline", "occluders", "camera_dropout", "low_rate", "crowd", "outside_cameras")


def _text(name: str) -> str:
    if name not in SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; expected one of {', '.join(SCENARIOS)}")
    return (resources.files("planefuse") / "data" / "scenarios" / f"{name}.yaml").read_text()


def scenario_description(name: str) -> str:
    """The scenario's description (the leading comment of its YAML file), one line."""
    lines = [ln[1:].strip() for ln in _text(name).splitlines() if ln.startswith("#")]
    return " ".join(lines)


def scenario_config(name: str, *, seed: int, duration_s: float) -> SceneConfig:
    """The :class:`SceneConfig` of scenario ``name`` with this seed and duration [s]."""
    fields = yaml.safe_load(_text(name)) or {}
    return SceneConfig(**fields, seed=int(seed), duration_s=float(duration_s))
