"""Typer application and the registry of subcommands."""

from __future__ import annotations

import json
import warnings
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import NoReturn

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from .. import __version__

app = typer.Typer(
    name="planefuse",
    help="Register cameras+IMU, laser range finders and binaural sound on planes parallel to the ground; "
    "fuse them in Bayesian occupancy grids and track people.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,
    # Help texts are shown verbatim: with rich markup "[m]", "[s]", "[deg]", "[dB]" would be read as style tags
    # and vanish. _register() gives every sub-application the same mode.
    rich_markup_mode=None,
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
    warnings.formatwarning = _one_line_warning


def _one_line_warning(message, category, filename, lineno, line=None) -> str:
    """A warning as the command line prints it: ``warning: MESSAGE`` on one line, without the source line of the
    library that raised it (a user's run reports a repair or a limit, not a program location)."""
    return f"warning: {' '.join(str(message).split())}\n"


def units_table(title: str, columns: Sequence[str], rows: Iterable[Sequence[object]],
                right: bool = True, caption: str | None = None) -> Table:
    """A rich table whose title, caption, headers and cells are printed verbatim (units like ``[m]`` are not
    markup).

    Cells wrap (they are never cut) so that the table fits the terminal; the first column is left-aligned,
    the others right-aligned when ``right``.
    """
    table = Table(title=escape(title), caption=escape(caption) if caption else None, show_edge=False)
    for i, col in enumerate(columns):
        table.add_column(escape(col), justify="right" if right and i else "left", overflow="fold")
    for row in rows:
        table.add_row(*(escape(str(v)) for v in row))
    return table


def exit_with_error(message: str, code: int = 2) -> NoReturn:
    """Print ``error: MESSAGE`` on one line (markup-free) and exit with ``code``."""
    console.print(f"[red]error:[/red] {escape(' '.join(str(message).split()))}", soft_wrap=True, highlight=False)
    raise typer.Exit(code)


def write_json(path: Path, obj) -> None:
    """Write ``obj`` as indented JSON to ``path`` (atomically) and say so."""
    from ..outputs import atomic_write_text

    atomic_write_text(path, json.dumps(obj, indent=2) + "\n")
    console.print(f"wrote {escape(str(path))}", highlight=False)


def _register() -> None:
    """Import every ``cli/_<name>.py`` module: each adds its commands to :data:`app` on import.

    Every sub-application then prints its help verbatim, as the root does (``rich_markup_mode``).
    """
    import importlib
    import pkgutil

    from . import __path__ as cli_path

    for mod in sorted(m.name for m in pkgutil.iter_modules(cli_path)):
        if mod.startswith("_") and mod != "_app":
            importlib.import_module(f"{__package__}.{mod}")
    groups = list(app.registered_groups)
    while groups:
        sub = groups.pop().typer_instance
        sub.rich_markup_mode = app.rich_markup_mode
        groups += sub.registered_groups


_register()


def main() -> None:
    """Entry point of the ``planefuse`` console script."""
    app()
