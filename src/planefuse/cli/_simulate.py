"""``planefuse simulate``: write a simulated multi-sensor recording with ground truth."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from ..io import DEFAULT_IMAGE_FORMAT
from ._app import app, console, exit_with_error


@app.command()
def simulate(
    scene: Path = typer.Argument(None, help="SCENE.yaml (see docs/simulator.md); omit for the built-in default scene."),
    out: Path = typer.Option(..., "--out", help="Output recording folder."),
    duration_s: float = typer.Option(None, "--duration-s", help="Override the scene's duration [s]."),
    seed: int = typer.Option(None, "--seed", help="Override the scene's random seed."),
    image_format: str = typer.Option(DEFAULT_IMAGE_FORMAT, "--image-format",
                                     help="bmp (uncompressed, fastest to read), png (lossless) or jpg (lossy, small)."),
    png_compression: int = typer.Option(0, "--png-compression", help="zlib level 0-9 of PNG frames: 0 = stored "
                                        "(about 1.7x the bytes of level 1 on simulated frames, read 9x faster)."),
    masks: bool = typer.Option(True, "--masks/--no-masks", help="Write ground-truth foreground masks."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Allow a non-empty output folder."),
) -> None:
    """Simulate people walking in a room seen by cameras+IMU (and laser, binaural head); write a recording."""
    from ..sim import default_scene_config, load_scene_config
    from ..sim import simulate as run

    try:
        cfg = load_scene_config(scene) if scene is not None else default_scene_config()
        over = {k: v for k, v in (("duration_s", duration_s), ("seed", seed)) if v is not None}
        if over:
            # Re-validate from the fields the user set, so that defaults derived from them (speakers) follow.
            cfg = type(cfg).model_validate({**cfg.model_dump(exclude_unset=True), **over})
        t0 = time.perf_counter()
        rec = run(cfg)
        manifest = rec.write(out, overwrite=overwrite, masks=masks, image_format=image_format,
                             png_compression=png_compression)
    except ValueError as exc:
        exit_with_error(str(exc))
    kinds = ", ".join(f"{s.type} {s.name}" for s in manifest.sensors)
    console.print(
        f"wrote {out} ({cfg.duration_s:g} s, {cfg.n_people} people; {kinds}) in {time.perf_counter() - t0:.1f} s",
        markup=False
    )
