"""``planefuse import OUT``: a recording folder from an installation's videos/images and calibration files."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import numpy as np
import typer

from ..calib import CALIBRATION_FORMATS, LENGTH_UNITS_M, check_metric_scale, load_cameras, load_ground_homographies
from ..io import (
    CameraInput,
    geometry_findings,
    import_recording,
    frame_times_of,
    people_from_boxes,
    probe_camera_input,
    read_control_points,
    read_ground_positions,
)
from ..pipeline import SystemParams
from rich.markup import escape

from ._app import app, console, exit_with_error

#: Margin [m] around the ground truth's extent when the monitored area is not given.
ROOM_MARGIN_M = 1.0


def _pairs(values: list[str], option: str) -> dict[str, str]:
    """``NAME=VALUE`` options -> dict; one-line error naming the option otherwise."""
    out: dict[str, str] = {}
    for v in values:
        name, sep, value = v.partition("=")
        if not sep or not name or not value:
            raise ValueError(f"{option} {v!r}: expected NAME=VALUE")
        if name in out:
            raise ValueError(f"{option}: camera {name!r} given twice")
        out[name] = value
    return out


def _floats(text: str, n: int | None, option: str) -> list[float]:
    try:
        vals = [float(x) for x in text.split(",")]
    except ValueError:
        raise ValueError(f"{option} {text!r}: expected comma-separated numbers") from None
    if n is not None and len(vals) != n:
        raise ValueError(f"{option} {text!r}: expected {n} numbers, got {len(vals)}")
    if not np.isfinite(vals).all():
        raise ValueError(f"{option} {text!r}: values must be finite")
    return vals


def _rects(values: list[str]) -> dict[str, list[tuple[int, int, int, int]]]:
    out: dict[str, list[tuple[int, int, int, int]]] = {}
    for v in values:
        name, sep, text = v.partition("=")
        if not sep:
            raise ValueError(f"--ignore-rect {v!r}: expected NAME=U_MIN,V_MIN,U_MAX,V_MAX")
        r = _floats(text, 4, "--ignore-rect")
        if any(x != int(x) for x in r) or not (0 <= r[0] < r[2] and 0 <= r[1] < r[3]):
            raise ValueError(f"--ignore-rect {v!r}: expected integer pixels with 0 <= U_MIN < U_MAX, 0 <= V_MIN < V_MAX")
        out.setdefault(name, []).append(tuple(int(x) for x in r))
    return out


def _size(text: str, option: str) -> tuple[int, int]:
    w, sep, h = text.lower().partition("x")
    if not sep or not w.isdigit() or not h.isdigit() or int(w) <= 0 or int(h) <= 0:
        raise ValueError(f"{option} {text!r}: expected WIDTHxHEIGHT in pixels, e.g. 360x288")
    return int(w), int(h)


def recording_check_config(folder: Path):
    """The run configuration ``planefuse check FOLDER`` uses for a recording folder, the one ``planefuse config
    init --recording FOLDER`` writes (:func:`planefuse.config.config_for_recording`), and what was chosen and why
    (messages)."""
    from ..config import config_for_recording
    from ..io import read_recording

    try:
        fit = config_for_recording(read_recording(folder))
    except (ValueError, OSError) as exc:
        exit_with_error(str(exc))
    return fit.config, fit.messages


@app.command("import")
def import_cmd(
    out: Path = typer.Argument(..., help="Recording folder to create (format 2)."),
    camera: list[str] = typer.Option([], "--camera", help="NAME=PATH: a camera's video file (mp4/avi/mkv/mov...) "
                                     "or folder of images (png/jpg..., ordered by the number in their names). "
                                     "Repeat per camera."),
    calib_format: str = typer.Option(..., "--calib-format", help="Calibration format: "
                                     f"{', '.join(CALIBRATION_FORMATS)}. opencv: FileStorage YAML/XML per camera "
                                     "(camera_matrix, distortion_coefficients, rvec/tvec or R/T); json: one file, "
                                     "VoxelPose/Panoptic layout; tsai: EPFL Tsai XML per camera; homography: 3x3 "
                                     "image -> ground text file per camera."),
    calib: list[str] = typer.Option([], "--calib", help="NAME=FILE per camera (json: NAME=FILE#KEY picks the "
                                    "file's camera KEY; a bare FILE serves every camera under its own name). "
                                    "Cameras with boxes but no frames need one too."),
    units: str = typer.Option(..., "--units", help="Length unit of the calibration's translations, the control "
                              "points and the ground-truth positions: mm, cm or m."),
    ground_unit_m: float = typer.Option(None, "--ground-unit-m", help="homography: metres per ground unit of the "
                                        "homographies [m] (EPFL terrace ~0.0219, laboratory 0.02)."),
    ground_flip_y: bool = typer.Option(False, "--ground-flip-y", help="homography: the ground frame's y axis is "
                                       "flipped (EPFL top views): flip it for a right-handed world, z up."),
    times: list[str] = typer.Option([], "--times", help="NAME=CSV: frame times, time_s,frame_index (video) or "
                                    "time_s,image_file (images). Default: start + k / rate."),
    rate: list[str] = typer.Option([], "--rate", help="NAME=HZ: frame rate [Hz] (videos: overrides the "
                                   "container's; image folders: required without --times)."),
    start_time_s: float = typer.Option(0.0, "--start-time-s", help="Time of frame 0 of every camera [s]."),
    image_size: list[str] = typer.Option([], "--image-size", help="NAME=WxH: image size [px] of a camera with "
                                         "boxes but no frames."),
    ignore_rect: list[str] = typer.Option([], "--ignore-rect", help="NAME=U_MIN,V_MIN,U_MAX,V_MAX: pixels that are "
                                          "not scene evidence (watermark, TV, privacy zone) [px, max exclusive]. "
                                          "Repeatable."),
    ignore_mask: list[str] = typer.Option([], "--ignore-mask", help="NAME=IMAGE: 8-bit mask of the frame size, "
                                          "non-zero = not evidence."),
    background: list[str] = typer.Option([], "--background", help="NAME=IMAGE: image of the empty scene (colour, "
                                         "the frames' size), priming the camera's background model."),
    background_median_s: float = typer.Option(None, "--background-median-s", help="Cameras without --background: "
                                              "estimate the empty scene as the per-pixel median of the camera's "
                                              "frames in their first S seconds [s] (people walking are removed, "
                                              "people standing still for half of it are not)."),
    gt_boxes: list[str] = typer.Option([], "--gt-boxes", help="NAME=FILE: person boxes with identities shared by "
                                       "the cameras; the feet go to the ground through each camera."),
    gt_format: str = typer.Option("mot", "--gt-format", help="Box file format: mot (MOTChallenge, 1-based "
                                  "frames) or vatic (EPFL gt.txt, 0-based frames)."),
    gt_positions: Path = typer.Option(None, "--gt-positions", help="CSV time_s,person_id,x,y or "
                                      "frame,person_id,x,y: ground-truth positions on the ground (--units)."),
    points: Path = typer.Option(None, "--points", help="CSV camera,u_px,v_px,x,y,z: pixels of known world points "
                                "(--units), reprojected by planefuse check."),
    planes: str = typer.Option(",".join(f"{h:g}" for h in SystemParams().heights_m), "--planes",
                               help="Suggested plane heights [m] (default: the library's)."),
    room: str = typer.Option(None, "--room", help="Monitored area X_MIN,X_MAX,Y_MIN,Y_MAX [m]; default: the "
                             "ground truth's extent + 1 m."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Write into a non-empty folder."),
) -> None:
    """Build a recording (scene.yaml, format 2) from videos or image folders and calibration files."""
    try:
        frames = _pairs(camera, "--camera")
        calib_files = _pairs([c if "=" in c else f"*={c}" for c in calib], "--calib")
        if "*" in calib_files:
            if calib_format != "json":
                raise ValueError(f"--calib {calib_files['*']}: a bare FILE serves every camera only for --calib-format "
                                 "json; give NAME=FILE")
            shared = calib_files.pop("*")
            calib_files = {n: shared for n in frames} | calib_files
        box_files = {k: Path(v) for k, v in _pairs(gt_boxes, "--gt-boxes").items()}
        sizes = {k: _size(v, "--image-size") for k, v in _pairs(image_size, "--image-size").items()}
        rates = {k: _floats(v, 1, "--rate")[0] for k, v in _pairs(rate, "--rate").items()}
        times_files = {k: Path(v) for k, v in _pairs(times, "--times").items()}
        masks = {k: Path(v) for k, v in _pairs(ignore_mask, "--ignore-mask").items()}
        plates = {k: Path(v) for k, v in _pairs(background, "--background").items()}
        rects = _rects(ignore_rect)
        for option, names in (("--times", times_files), ("--rate", rates), ("--ignore-mask", masks),
                              ("--ignore-rect", rects), ("--background", plates)):
            extra = sorted(set(names) - set(frames))
            if extra:
                raise ValueError(f"{option} names camera {extra[0]!r}, which has no --camera frames")
        for name in list(frames) + list(box_files):
            if name not in calib_files:
                raise ValueError(f"camera {name!r} has no calibration: give --calib {name}=FILE")
        if units not in LENGTH_UNITS_M:
            raise ValueError(f"--units {units!r}: use one of {', '.join(LENGTH_UNITS_M)}")
        inputs = [CameraInput(n, Path(p), times_files.get(n), rates.get(n), start_time_s, tuple(rects.get(n, ())),
                              masks.get(n), plates.get(n), None if n in plates else background_median_s)
                  for n, p in frames.items()]
        probes = {i.name: probe_camera_input(i) for i in inputs}
        sizes |= {n: (p.width_px, p.height_px) for n, p in probes.items()}
        cameras, notes = load_cameras(calib_format, {n: calib_files[n] for n in set(frames) | set(box_files)},
                                      unit=units, sizes_px=sizes, ground_unit_m=ground_unit_m,
                                      ground_flip_y=ground_flip_y)
        first = probes[inputs[0].name] if inputs else None
        people = None
        if box_files:
            if first is None:
                raise ValueError("--gt-boxes needs at least one --camera: its frame times date the boxes' frames")
            homs = load_ground_homographies({n: calib_files[n] for n in box_files}, ground_unit_m=ground_unit_m,
                                            ground_flip_y=ground_flip_y) if calib_format == "homography" else None
            people, gt_notes = people_from_boxes(cameras, box_files, gt_format, frame_times_s=frame_times_of(first),
                                                 H_ground_image=homs)
            notes += [("info", n) for n in gt_notes]
        elif gt_positions is not None:
            people = read_ground_positions(gt_positions, LENGTH_UNITS_M[units],
                                           rate_hz=first.rate_hz if first else None, start_time_s=start_time_s)
        room_xy = tuple(_floats(room, 4, "--room")) if room else None
        if room_xy is None and people is not None:
            xy = people.xy_m.reshape(-1, 2)
            xy = xy[np.isfinite(xy).all(axis=1)]
            room_xy = (float(xy[:, 0].min() - ROOM_MARGIN_M), float(xy[:, 0].max() + ROOM_MARGIN_M),
                       float(xy[:, 1].min() - ROOM_MARGIN_M), float(xy[:, 1].max() + ROOM_MARGIN_M))
        check_metric_scale(cameras, units, source=f"--calib-format {calib_format} --units {units}", room_xy_m=room_xy)
        if room_xy is not None and max(room_xy[1] - room_xy[0], room_xy[3] - room_xy[2]) > 1000.0:
            raise ValueError(f"monitored area {np.round(room_xy, 1).tolist()} m is over 1 km across: a length unit is "
                             f"wrong (--units {units}, --room is in metres)")
        control = read_control_points(points, LENGTH_UNITS_M[units]) if points is not None else None
        heights = _floats(planes, None, "--planes")
        report = import_recording(out, inputs, cameras, planes_heights_m=heights, room_xy_m=room_xy, people=people,
                                  control_points=control, overwrite=overwrite, probes=probes,
                                  source="planefuse import " + " ".join(shlex.quote(a) for a in sys.argv[2:]))
    except (ValueError, OSError) as exc:
        exit_with_error(str(exc))
    notes = [("info", n) for n in report.notes] + notes
    findings = geometry_findings([cameras[n] for n in frames], heights, control_points=control, people=people)
    for level, subject, message in [(lv, "import", n) for lv, n in notes] + list(findings):
        console.print(escape(f"{level}: {subject}: {message}"), soft_wrap=True, highlight=False)
    console.print(f"wrote {out / 'scene.yaml'}; next: planefuse check {out}, then planefuse config init run.yaml "
                  f"--recording {out}", highlight=False)
    if any(level == "error" for level, _, _ in findings):
        raise typer.Exit(1)
