"""A run plan: what to run, what to write and where, and the key under which a run can be resumed."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field, is_dataclass
from pathlib import Path

import numpy as np

from ..io import MANIFEST_NAME, Recording
from ..outputs import OutputSettings
from ._system import SystemParams

__all__ = ["RunPlan", "resume_key"]


@dataclass(frozen=True)
class RunPlan:
    """Everything a run needs besides its recording: built once, from a configuration
    (:meth:`planefuse.config.RunConfig.plan`) or in code, and used by ``planefuse run``, ``demo``,
    ``batch`` and the scripts alike.

    Attributes
    ----------
    params : SystemParams
        What to run.
    out_dir : Path or None
        Output folder; None: the run is evaluated in memory and nothing is written.
    outputs : OutputSettings
        What is written besides the tables.
    config_text : str
        The configuration as YAML, copied to ``config.yaml`` and the report ("" = ``params`` as JSON).
    config_key : str
        Fingerprint of everything in the configuration that changes results (:func:`planefuse.config.
        config_hash`; "" = a hash of ``params``). With the recording's fingerprint it is the resume key: a
        run resumes a folder holding an interrupted run with the same key.
    resume : bool
        False: start afresh even where the folder holds a resumable run (or another run's results).
    force : bool
        Write into an out_dir holding another run's results (replaced) or files no run wrote (kept).
    """

    params: SystemParams = field(default_factory=SystemParams)
    out_dir: Path | None = None
    outputs: OutputSettings = field(default_factory=OutputSettings)
    config_text: str = ""
    config_key: str = ""
    resume: bool = True
    force: bool = False

    def text(self) -> str:
        """:attr:`config_text`, or the parameters as JSON."""
        return self.config_text or params_text(self.params)


def params_text(params: SystemParams) -> str:
    """``params`` as indented JSON (paths and other objects as their ``repr``)."""

    def plain(o):
        if is_dataclass(o):
            return {k: plain(v) for k, v in asdict(o).items()}
        if isinstance(o, (list, tuple)):
            return [plain(v) for v in o]
        if isinstance(o, np.ndarray):
            return o.tolist()
        return o if isinstance(o, (int, float, str, bool, type(None))) else repr(o)

    return json.dumps(plain(params), indent=1, sort_keys=True, default=repr)


def recording_fingerprint(rec: Recording) -> str:
    """What identifies the recording for resuming: its source and duration, plus its manifest (read from disk)
    or its simulation configuration (in memory), so that a changed recording is not resumed."""
    parts = [repr(rec.source), repr(rec.duration_s)]
    manifest = None if rec.root is None else Path(rec.root) / MANIFEST_NAME
    if manifest is not None and manifest.is_file():
        parts.append(hashlib.sha256(manifest.read_bytes()).hexdigest())
    elif rec.provenance is not None:
        parts.append(json.dumps(rec.provenance, sort_keys=True, default=repr))
    return "\n".join(parts)


def resume_key(plan: RunPlan, rec: Recording) -> str:
    """The key of a run of ``plan`` on ``rec`` (16 hex digits): its configuration's key, the recording's
    fingerprint and, with a YOLOX person detector, the model file's SHA-256 and the engine that runs it (a model
    replaced at the same path, or ``person_engine: auto`` finding another engine installed, is another run);
    output options that do not change results (figures, report, out_dir, ...) are not in it."""
    key = plan.config_key or hashlib.sha256(params_text(plan.params).encode()).hexdigest()
    fg = plan.params.camera_params.foreground
    if fg.person_detector == "yolox" and fg.person_model is not None:
        from ..vision import model_sha256, resolve_engine

        key += f"\nperson model {model_sha256(fg.person_model)} run by {resolve_engine(fg.person_engine)}"
    return hashlib.sha256((key + "\n" + recording_fingerprint(rec)).encode()).hexdigest()[:16]
