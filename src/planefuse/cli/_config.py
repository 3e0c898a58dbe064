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
from ._app import app, console, exit_with_error

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
                                  "[m], the sensors it has and the settings of its profile; otherwise every field "
                                  "is at its default. Written relative to the configuration's folder, as the "
                                  "configuration reads it."),
    profile: str = typer.Option("auto", "--profile", help="Settings for what the recording is: auto (from the "
                                "recording: simulated, or real-video for imported camera video), "
                                "simulated (the library's defaults) or real-video (chosen on the EPFL terrace; "
                                "planefuse.config.REAL_VIDEO)."),
    person_model: Path | None = typer.Option(None, "--person-model", help="A YOLOX ONNX file you downloaded (e.g. "
                                             "yolox_nano.onnx from the YOLOX project's releases): the cameras run "
                                             "it as their person detector (docs/cameras.md, 'Person detector')."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing file."),
) -> None:
    """Write a commented example configuration (every field, its unit and range); for an existing recording, the
    configuration that suits it."""
    from ..config import PROFILES, config_for_recording
    from ..io import read_recording

    if path.exists() and not force:
        console.print(f"[red]{escape(str(path))} exists[/]; use --force to overwrite it")
        raise typer.Exit(1)
    if profile != "auto" and profile not in PROFILES:
        exit_with_error(f"--profile {profile!r}: use auto, {', '.join(PROFILES)}", 2)
    fitted, notes, header = None, None, ()
    if (Path(recording) / "scene.yaml").is_file():
        try:
            model = None
            if person_model is not None:
                from ..vision import load_yolox

                load_yolox(person_model)  # a missing file or another layout: one line now, not at the run
                model = os.path.relpath(person_model.resolve(), path.resolve().parent)
            fit = config_for_recording(read_recording(Path(recording)), None if profile == "auto" else profile,
                                       model)
        except (ValueError, OSError) as exc:
            exit_with_error(str(exc), 1)
        fitted, notes = fit.config, fit.profile.notes()
        header = (f"Profile {fit.profile.name} (planefuse.config.PROFILES): {fit.profile.description}.",)
        for m in fit.messages:
            console.print(escape(m), highlight=False)
        s = fitted.sensors
        used = [n for n, on in (("cameras", s.cameras.enabled), ("laser", s.laser.enabled), ("sound", s.sound.enabled))
                if on]
        area = (f"area x {list(fitted.planes.x_range_m)} y {list(fitted.planes.y_range_m)} m"
                if fitted.planes.x_range_m is not None else
                f"area: the recording's room less {fitted.planes.wall_margin_m:g} m")
        console.print(f"{escape(recording)}: planes at z = {', '.join(f'{h:g}' for h in fitted.planes.heights_m)} m, "
                      f"{area}, sensors {', '.join(used) or 'none'} (those the recording has)", highlight=False)
    elif profile != "auto":
        exit_with_error(f"--profile {profile}: needs an existing --recording (a folder with scene.yaml)", 2)
    elif person_model is not None:
        exit_with_error("--person-model: needs an existing --recording (a folder with scene.yaml)", 2)
    where = recording
    if recording != EXAMPLE_RECORDING and not Path(recording).is_absolute():
        # the configuration's paths are relative to its own folder, the option's to the working directory
        where = os.path.relpath(Path(recording).resolve(), path.resolve().parent)
    atomic_write_text(path, example_yaml(where, fitted, notes=notes, header=header))
    console.print(f"wrote {escape(str(path))}; edit it, then run [bold]planefuse check {escape(str(path))}[/]")


@config_app.command("show")
def config_show(path: Path = typer.Argument(..., help="Configuration file.")) -> None:
    """Validate a configuration and print it with every default filled in and paths resolved."""
    try:
        cfg = load_config(path)
    except ConfigError as err:
        exit_on_config_error(err)
    typer.echo(yaml.safe_dump(cfg.model_dump(mode="json"), sort_keys=False), nl=False)
