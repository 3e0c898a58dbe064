"""Typer application and the registry of subcommands."""

from __future__ import annotations

import typer
from rich.console import Console

from .. import __version__

app = typer.Typer(
    name="planefuse",
    help="Register cameras+IMU, laser range finders and binaural sound on planes parallel to the ground; "
    "fuse them in Bayesian occupancy grids and track people.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,
)
console = Console()


def _version_callback(value: bool) -> None:
    if value:
        console.print(f"planefuse {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_version_callback, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """planefuse command line."""


def _register() -> None:
    # Each module adds its commands to ``app`` on import.
    from . import _demo  # noqa: F401
    from . import _simulate  # noqa: F401
    from . import _calib  # noqa: F401
    from . import _cameras  # noqa: F401


_register()


def main() -> None:
    """Entry point of the ``planefuse`` console script."""
    app()
