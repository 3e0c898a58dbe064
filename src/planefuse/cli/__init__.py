"""The ``planefuse`` command line: a thin typer layer over the library.

Each subcommand lives in its own module and registers itself on :data:`app`.
"""

from ._app import app, main

__all__ = ["app", "main"]
