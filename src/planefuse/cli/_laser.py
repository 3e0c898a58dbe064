"""``planefuse laser-map``: occupancy map of a 2-D laser log with corrected poses."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import typer
from rich.table import Table

from ._app import app, console


@app.command("laser-map")
def laser_map(
    log_path: Path = typer.Argument(..., help="CARMEN log (.log or .log.gz) with corrected poses."),
    out: Path = typer.Option(..., "--out", help="PNG to write."),
    cell_size_m: float = typer.Option(0.05, help="Cell side [m]."),
    reference: Path = typer.Option(None, help="Reference map image to show beside ours."),
) -> None:
    """Register every scan of LOG_PATH with its pose into an occupancy map; print sharpness measures."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..grid import probability_from_log_odds
    from ..laser import NonMonotonicTimeWarning, map_entropy_bits, map_from_carmen_log, read_carmen_log, wall_spread_m

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", NonMonotonicTimeWarning)
        log = read_carmen_log(log_path)
    for w in caught:
        console.print(f"[yellow]warning:[/] {w.message}")
    m, pts = map_from_carmen_log(log, cell_size_m=cell_size_m)
    lo = m.log_odds[0]
    entropy = map_entropy_bits(lo)
    spread = float(np.median(wall_spread_m(pts)))
    table = Table(title=f"laser map of {log_path.name}")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    for k, v in [("scans", m.n_scans), ("time stamps going backwards", log.n_time_backwards),
                 ("real returns", m.n_valid), ("max-range readings", m.n_no_return),
                 ("invalid returns", m.n_invalid), ("grid (ny x nx)", f"{lo.shape[0]} x {lo.shape[1]}"),
                 ("cell size (m)", cell_size_m), ("map entropy of observed cells (bit)", f"{entropy:.3f}"),
                 ("median wall spread, RMS to local line (mm)", f"{1e3 * spread:.1f}")]:
        table.add_row(k, str(v))
    console.print(table)
    n_ax = 2 if reference is not None else 1
    fig, axes = plt.subplots(1, n_ax, figsize=(8 * n_ax, 8), squeeze=False)
    ax = axes[0, 0]
    ax.imshow(1.0 - probability_from_log_odds(lo), cmap="gray", origin="lower", extent=m.stack.extent_m,
              vmin=0, vmax=1, interpolation="antialiased")
    ax.set_title(f"{log_path.name}: {m.n_scans} scans, {cell_size_m * 100:.0f} cm cells\n"
                 f"entropy {entropy:.3f} bit, wall spread {1e3 * spread:.1f} mm")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if reference is not None:
        import imageio.v3 as iio

        axes[0, 1].imshow(iio.imread(reference))
        axes[0, 1].set_title(f"reference: {reference.name}")
        axes[0, 1].axis("off")
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=150)
    plt.close(fig)
    console.print(f"wrote {out}")
