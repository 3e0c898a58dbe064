"""Pre-run checks of a recording against a configuration (``planefuse check``).

:func:`check_recording` takes what a recording reader yields -- calibrated
cameras and the time stamps of every stream -- so it runs without the data
itself and is independent of the recording format.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from ..geometry import PinholeCamera
from ..grid import PlaneStack
from ..io import geometry_findings
from ..registration import ImagePlaneLookup

__all__ = ["CheckIssue", "CheckReport", "check_recording"]


@dataclass(frozen=True)
class CheckIssue:
    """One finding: ``level`` is ``"error"`` (the run would fail or be wrong), ``"warning"`` or ``"info"``."""

    level: Literal["error", "warning", "info"]
    subject: str
    message: str


@dataclass
class CheckReport:
    """All findings of :func:`check_recording`.

    Attributes
    ----------
    issues : list of CheckIssue
    camera_visible_fraction : dict
        Camera name -> fraction of cells seen on each plane, shape (L,).
    coverage_fraction : ndarray, shape (L,)
        Fraction of each plane's cells seen by at least one camera.
    """

    issues: list[CheckIssue] = field(default_factory=list)
    camera_visible_fraction: dict[str, np.ndarray] = field(default_factory=dict)
    coverage_fraction: np.ndarray | None = None

    @property
    def ok(self) -> bool:
        """True when no finding is an error."""
        return not self.errors

    @property
    def errors(self) -> list[CheckIssue]:
        return [i for i in self.issues if i.level == "error"]

    @property
    def warnings(self) -> list[CheckIssue]:
        return [i for i in self.issues if i.level == "warning"]

    def add(self, level: Literal["error", "warning", "info"], subject: str, message: str) -> None:
        self.issues.append(CheckIssue(level, subject, message))


def _check_stream(report: CheckReport, name: str, t: np.ndarray, gap_factor: float) -> tuple[float, float] | None:
    t = np.asarray(t, dtype=float).ravel()
    if t.size == 0:
        report.add("error", name, "stream has no samples")
        return None
    bad = ~np.isfinite(t)
    if bad.any():
        report.add("error", name, f"{int(bad.sum())} of {t.size} time stamps are NaN/inf")
        t = t[~bad]
        if t.size == 0:
            return None
    dt = np.diff(t)
    back = int(np.count_nonzero(dt <= 0))
    if back:
        report.add("error", name, f"{back} time stamps do not increase (first at sample {int(np.argmax(dt <= 0)) + 1})")
    fwd = dt[dt > 0]
    if fwd.size >= 2:
        med = float(np.median(fwd))
        gaps = int(np.count_nonzero(fwd > gap_factor * med))
        if gaps:
            report.add(
                "warning", name,
                f"{gaps} gap(s) longer than {gap_factor:g} x the median period {med * 1e3:.3g} ms "
                f"(longest {fwd.max():.3g} s)",
            )
        report.add("info", name, f"{t.size} samples, {t[0]:.3f}..{t[-1]:.3f} s, median rate {1.0 / med:.4g} Hz")
    return float(t.min()), float(t.max())


def check_recording(
    cameras: Sequence[PinholeCamera],
    stack: PlaneStack,
    stream_times_s: Mapping[str, np.ndarray],
    expected_streams: Iterable[str] = (),
    *,
    min_visible_fraction: float = 0.05,
    gap_factor: float = 10.0,
    recording=None,
) -> CheckReport:
    """Check that a recording can be run with a configuration, without running it.

    Parameters
    ----------
    cameras : sequence of PinholeCamera
        The calibrated cameras of the enabled camera streams (world frame, metres).
    stack : PlaneStack
        The configured plane stack.
    stream_times_s : mapping of str -> ndarray, shape (N,)
        Time stamps [s] of every stream found in the recording, on the common clock.
    expected_streams : iterable of str
        Streams the configuration needs (e.g. each enabled camera, ``"laser"``).
    min_visible_fraction : float
        A camera seeing less than this fraction of the ground plane's cells
        gets a warning (none at all on any plane is an error).
    gap_factor : float
        A sampling interval longer than this many median periods is reported.
    recording : planefuse.io.Recording, optional
        Its control points and ground truth are checked against the cameras too
        (:func:`planefuse.io.geometry_findings`: planes above a camera, reprojection).

    Returns
    -------
    CheckReport
        ``report.ok`` is False when any finding is an error.
    """
    report = CheckReport()
    for name in expected_streams:
        if name not in stream_times_s:
            report.add("error", name, f"stream required by the configuration is missing (found: "
                       f"{', '.join(sorted(stream_times_s)) or 'none'})")
    spans = {}
    for name, t in stream_times_s.items():
        span = _check_stream(report, name, t, gap_factor)
        if span is not None:
            spans[name] = span
    if len(spans) >= 2:
        start = max(s[0] for s in spans.values())
        end = min(s[1] for s in spans.values())
        if end <= start:
            report.add("error", "streams", f"streams do not overlap in time (latest start {start:.3f} s >= "
                       f"earliest end {end:.3f} s)")
        else:
            report.add("info", "streams", f"all streams overlap on {start:.3f}..{end:.3f} s ({end - start:.3f} s)")

    seen_by = np.zeros(stack.shape, dtype=np.int32)
    for cam in cameras:
        vis = ImagePlaneLookup.from_camera(cam, stack).visible
        frac = vis.reshape(stack.n_planes, -1).mean(axis=1)
        report.camera_visible_fraction[cam.name] = frac
        seen_by += vis
        if not vis.any():
            report.add("error", cam.name, "the camera sees no cell of any plane (check its pose and the grid extent)")
        elif frac[0] < min_visible_fraction:
            report.add("warning", cam.name, f"the camera sees only {frac[0]:.1%} of the plane at "
                       f"{stack.heights_m[0]:g} m (< {min_visible_fraction:.0%})")
        else:
            report.add("info", cam.name, "sees " + ", ".join(
                f"{f:.0%} @ {h:g} m" for f, h in zip(frac, stack.heights_m)))
    for level, subject, message in geometry_findings(
            cameras, stack.heights_m, control_points=getattr(recording, "calibration_points", None),
            people=getattr(getattr(recording, "groundtruth", None), "people", None)):
        report.add(level, subject, message)
    if cameras:
        cov = (seen_by > 0).reshape(stack.n_planes, -1).mean(axis=1)
        report.coverage_fraction = cov
        multi = (seen_by >= 2).reshape(stack.n_planes, -1).mean(axis=1)
        report.add("info", "cameras", f"ground plane seen by >= 1 camera: {cov[0]:.0%}, by >= 2: {multi[0]:.0%}")
    return report
