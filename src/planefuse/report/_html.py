"""``report.html``: one self-contained page per run (figures inlined as base64 PNG, no external resources)."""

from __future__ import annotations

import base64
import datetime as _dt
import html
import platform
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..outputs._atomic import atomic_write_text

__all__ = ["write_report", "render_report", "library_versions"]

_LIBRARIES = ("numpy", "scipy", "opencv-python-headless", "numba", "pydantic", "matplotlib", "zarr", "imageio",
              "rerun-sdk", "motmetrics", "pyroomacoustics")

_TITLES = {
    "occupancy_last": "Occupancy per plane at the last step, with detections and tracks",
    "occupancy_mean": "Mean occupancy over the run, with all tracks",
    "saliency": "Auditory saliency over time",
    "laser_points": "Laser points per plane",
    "metrics": "Metrics",
}

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,sans-serif;margin:2em auto;max-width:1100px;color:#222;padding:0 1em}
h1{font-size:1.6em;margin-bottom:.2em} h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0} td,th{border:1px solid #ddd;padding:.25em .7em;text-align:left}
th{background:#f4f4f4} td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1em 0} figure img{max-width:100%;border:1px solid #eee} figcaption{color:#555;font-size:.9em}
pre{background:#f7f7f7;padding:1em;overflow-x:auto;font-size:.85em} .muted{color:#777}
"""


def library_versions() -> dict[str, str]:
    """Versions of Python, planefuse and the libraries a run depends on ("not installed" where absent)."""
    out = {"python": platform.python_version(), "planefuse": __version__}
    for name in _LIBRARIES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _fmt(v: Any) -> str:
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.4g}"
    return str(v)


def _table(rows: Mapping[str, Any], head: tuple[str, str]) -> str:
    body = "".join(
        f"<tr><td>{html.escape(str(k))}</td><td class='num'>{html.escape(_fmt(v))}</td></tr>" for k, v in rows.items()
    )
    return f"<table><tr><th>{head[0]}</th><th>{head[1]}</th></tr>{body}</table>"


def _metric_rows(metrics: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, str]]:
    scalars, series = {}, {}
    for k, v in metrics.items():
        if isinstance(v, (list, tuple, np.ndarray)):
            a = np.asarray([np.nan if x is None else x for x in v], dtype=float) if len(v) else np.zeros(0)
            series[k] = (f"{a.size} values, mean {np.nanmean(a):.4g}, min {np.nanmin(a):.4g}, max {np.nanmax(a):.4g}"
                         if a.size and np.isfinite(a).any() else f"{a.size} values")
        elif isinstance(v, Mapping):
            for kk, vv in v.items():
                scalars[f"{k}.{kk}"] = vv
        else:
            scalars[k] = v
    return scalars, series


def render_report(
    figures: Mapping[str, bytes],
    metrics: Mapping[str, Any],
    config_text: str,
    *,
    run_summary: Mapping[str, Any] | None = None,
    title: str = "planefuse run report",
    versions: Mapping[str, str] | None = None,
) -> str:
    """The HTML text of the report.

    Parameters
    ----------
    figures : dict of str -> bytes
        PNG images keyed by name (shown in this order; known names get captions).
    metrics : dict
        Scalars (and nested dicts of scalars) go to a table, lists to a series summary.
    config_text : str
        The run's configuration YAML, shown verbatim.
    run_summary : dict, optional
        Counts and facts about the run (steps, grid, tracks...).
    versions : dict, optional
        Library versions; :func:`library_versions` by default.
    """
    versions = library_versions() if versions is None else versions
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    parts = [
        "<!DOCTYPE html>",
        "<html lang='en'><head><meta charset='utf-8'>",
        "<meta name='viewport' content='width=device-width,initial-scale=1'>",
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1><p class='muted'>generated {now} by planefuse {html.escape(__version__)}</p>",
    ]
    if run_summary:
        parts += ["<h2 id='summary'>Run</h2>", _table(run_summary, ("item", "value"))]
    scalars, series = _metric_rows(metrics)
    parts.append("<h2 id='metrics'>Metrics</h2>")
    if scalars or series:
        if "moda" not in metrics:
            parts.append("<p class='muted'>No scores: the recording has no people ground truth (or ends within the "
                         "evaluation's first second); what the run consumed and produced.</p>")
        if scalars:
            parts.append(_table(scalars, ("metric", "value")))
        if series:
            parts.append(_table(series, ("per-step metric", "summary")))
    else:
        parts.append("<p class='muted'>No metrics were computed for this run (no ground truth?).</p>")
    parts.append("<h2 id='figures'>Figures</h2>")
    if not figures:
        parts.append("<p class='muted'>No figures.</p>")
    for name, png in figures.items():
        caption = _TITLES.get(name, name.replace("_", " "))
        if name.startswith("camera_") and name.endswith("_tracks"):
            caption = f"Camera {name[7:-7]}: frames with the tracks drawn from the feet to the head"
        elif name.startswith("camera_"):
            caption = f"Camera {name[7:]} with the registered plane grids"
        b64 = base64.b64encode(png).decode("ascii")
        parts.append(f"<figure id='fig-{html.escape(name)}'><img alt='{html.escape(caption)}' "
                     f"src='data:image/png;base64,{b64}'><figcaption>{html.escape(caption)}</figcaption></figure>")
    parts += [
        "<h2 id='configuration'>Configuration</h2>", f"<pre>{html.escape(config_text or '(not recorded)')}</pre>",
        "<h2 id='versions'>Versions</h2>", _table(versions, ("package", "version")),
        "</body></html>",
    ]
    return "\n".join(parts) + "\n"


def write_report(path: Path | str, figures: Mapping[str, bytes], metrics: Mapping[str, Any], config_text: str,
                 **kwargs: Any) -> Path:
    """Render the report (see :func:`render_report`) and write it atomically to ``path``."""
    path = Path(path)
    atomic_write_text(path, render_report(figures, metrics, config_text, **kwargs))
    return path
