"""The live configuration (``planefuse live LIVE.yaml``): a run configuration and the cameras' streams.

.. code-block:: yaml

    run: run.yaml                    # the run configuration: its recording gives the calibrations, its fields
                                     # the system's parameters, its outputs.out_dir the output folder
    cameras:                         # every camera of that recording -> its stream
      cam0: rtsp://10.0.0.21/stream1
      cam1: http://10.0.0.22:8080/video.mjpg
      cam2: 0                        # a local device (index, or /dev/video0)
      cam3: videos/cam3.mp4          # a video file played at its own rate
    clock: arrival                   # or presentation (the streams' own time stamps, one clock)

Every other field is :class:`planefuse.live.LiveSettings`'s, with its default there.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from ._run import LiveSettings

__all__ = ["LiveConfig", "load_live_config"]

_DEFAULTS = LiveSettings()


class LiveConfig(BaseModel):
    """A validated live configuration (module docstring); defaults from :class:`LiveSettings`."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    run: Path
    cameras: dict[str, str | int]
    clock: str = _DEFAULTS.clock
    queue_frames: int = _DEFAULTS.queue_frames
    sync_wait_s: float | None = _DEFAULTS.sync_wait_s
    stall_s: float = _DEFAULTS.stall_s
    retry_min_s: float = _DEFAULTS.retry_min_s
    retry_max_s: float = _DEFAULTS.retry_max_s
    serve: bool = _DEFAULTS.serve
    host: str = _DEFAULTS.host
    port: int = _DEFAULTS.port
    page_rate_hz: float = _DEFAULTS.page_rate_hz
    trail_s: float = _DEFAULTS.trail_s
    page_width_px: int = _DEFAULTS.page_width_px
    checkpoint_steps: int = _DEFAULTS.checkpoint_steps
    #: ``"-"``: tracks as JSON lines on standard output; a path: in that file; null: none
    tracks_jsonl: str | None = None
    #: the output folder (tracks.csv, tracks_mot.txt, live_report.json); null: ``live/`` in the run
    #: configuration's outputs.out_dir (beside, not over, a recording run's results)
    out_dir: Path | None = None

    def settings(self) -> LiveSettings:
        """The :class:`LiveSettings` these fields set (every field but ``run``, ``tracks_jsonl``, ``out_dir``)."""
        return LiveSettings(**{f.name: getattr(self, f.name) for f in fields(LiveSettings)})


def load_live_config(path: str | Path) -> LiveConfig:
    """Read and validate a live configuration; ``run``, ``out_dir``, a ``tracks_jsonl`` file and video-file
    cameras are made absolute against the file's folder.

    Raises
    ------
    ValueError
        One line naming the file and the field: unreadable, not YAML, an unknown or invalid field.
    """
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as err:
        raise ValueError(f"{path}: cannot read the file: {err.strerror or err}") from None
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not valid YAML: {err}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: the file must hold a YAML mapping, got {type(data).__name__}")
    try:
        cfg = LiveConfig.model_validate(data)
        cfg.settings()
    except ValidationError as err:
        e = err.errors()[0]
        where = ".".join(str(p) for p in e["loc"]) or "(top level)"
        raise ValueError(f"{path}: {where}: {e['msg']} (got {e.get('input')!r})") from None
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None
    base = path.resolve().parent
    cameras: dict[str, Any] = {}
    for name, src in cfg.cameras.items():
        if isinstance(src, str) and "://" not in src and not src.startswith("/dev/video"):
            src = str(base / src)
        cameras[name] = src
    jsonl = cfg.tracks_jsonl
    if jsonl is not None and jsonl != "-":
        jsonl = str(base / jsonl)
    return cfg.model_copy(update={"run": base / cfg.run, "cameras": cameras, "tracks_jsonl": jsonl,
                                  "out_dir": None if cfg.out_dir is None else base / cfg.out_dir})
