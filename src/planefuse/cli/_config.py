"""``planefuse config init|show``: write the commented example configuration, or print a validated one."""

from __future__ import annotations

import os
from pathlib import Path

import typer
import yaml
from rich.markup import escape

from ..config import ConfigError, example_yaml, load_config
from ..config._load import EXAMPLE_RECORDING
from ..outputs import atomic_write_text
from ._app import app, console

config_app = typer.Typer(help="Write or inspect a run configuration (YAML).", no_args_is_help=True)
app.add_typer(config_app, name="config")


def exit_on_config_error(err: ConfigError) -> None:
    """Print a :class:`ConfigError` readably (each issue on one line, not wrapped) and exit with status 2."""
    console.print(f"[bold red]invalid configuration[/] {escape(str(err.file))}", highlight=False, soft_wrap=True)
    for it in err.issues:
        where = f"{err.file}:{it.line}" if it.line else str(err.file)
        exp = f" (expected: {it.expected})" if it.expected else ""
        console.print(f"  [red]x[/] {escape(where)}: [bold]{escape(it.field_path or '<file>')}[/]: "
                      f"{escape(it.message + exp)}", highlight=False, soft_wrap=True)
    raise typer.Exit(2)


@config_app.command("init")
def config_init(
    path: Path = typer.Argument(Path("planefuse.yaml"), help="Where to write the example configuration."),
    recording: str = typer.Option(EXAMPLE_RECORDING, help="Recording folder to put in the example. An existing "
                                  "recording (a folder with scene.yaml) also sets the planes, the monitored area "
                                  "[m] and the sensors it has; otherwise every field is at its default. Written "
                                  "relative to the configuration's folder, as the configuration reads it."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing file."),
) -> None:
    """Write a commented example configuration (every field, its unit and range)."""
    from ._import import recording_check_config

    if path.exists() and not force:
        console.print(f"[red]{escape(str(path))} exists[/]; use --force to overwrite it")
        raise typer.Exit(1)
    fitted = None
    if (Path(recording) / "scene.yaml").is_file():
        fitted = recording_check_config(Path(recording))
        s = fitted.sensors
        used = [n for n, on in (("cameras", s.cameras.enabled), ("laser", s.laser.enabled), ("sound", s.sound.enabled))
                if on]
        console.print(f"{escape(recording)}: planes at z = {', '.join(f'{h:g}' for h in fitted.planes.heights_m)} m, "
                      f"area x {fitted.planes.x_range_m} y {fitted.planes.y_range_m} m, sensors "
                      f"{', '.join(used) or 'none'} (those the recording has)", highlight=False)
    where = recording
    if recording != EXAMPLE_RECORDING and not Path(recording).is_absolute():
        # the configuration's paths are relative to its own folder, the option's to the working directory
        where = os.path.relpath(Path(recording).resolve(), path.resolve().parent)
    atomic_write_text(path, example_yaml(where, fitted))
    console.print(f"wrote {escape(str(path))}; edit it, then run [bold]planefuse check {escape(str(path))}[/]")


@config_app.command("show")
def config_show(path: Path = typer.Argument(..., help="Configuration file.")) -> None:
    """Validate a configuration and print it with every default filled in and paths resolved."""
    try:
        cfg = load_config(path)
    except ConfigError as err:
        exit_on_config_error(err)
    typer.echo(yaml.safe_dump(cfg.model_dump(mode="json"), sort_keys=False), nl=False)
