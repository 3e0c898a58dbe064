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
    """Import every ``cli/_<name>.py`` module: each adds its commands to :data:`app` on import."""
    import importlib
    import pkgutil

    from . import __path__ as cli_path

    for mod in sorted(m.name for m in pkgutil.iter_modules(cli_path)):
        if mod.startswith("_") and mod != "_app":
            importlib.import_module(f"{__package__}.{mod}")


_register()


def main() -> None:
    """Entry point of the ``planefuse`` console script."""
    app()
