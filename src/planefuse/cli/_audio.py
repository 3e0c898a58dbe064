"""``planefuse audio ...``: calibrate the binaural sensor model, localise a recording, evaluate a sweep."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import typer

from ._app import app, console, exit_with_error, units_table

audio_app = typer.Typer(help="Binaural sound: calibration, localisation, evaluation.", no_args_is_help=True)
app.add_typer(audio_app, name="audio")


_INTERPOLATION_HELP = ("Measured HRIRs between measured directions: 'barycentric' (onset-aligned interpolation) "
                       "or 'nearest' (snap to the nearest measured direction).")


def _head(spec: str, fs_hz: float, interpolation: str = "barycentric"):
    """The head model of ``--head``; its warnings (sparse grid, old SOFA version) printed on one line each."""
    from ..audio import HRIR_INTERPOLATIONS, HrirWarning, MeasuredHrirs, SphericalHead

    if interpolation not in HRIR_INTERPOLATIONS:
        exit_with_error(f"--hrir-interpolation must be one of {', '.join(HRIR_INTERPOLATIONS)}, got {interpolation!r}")
    if spec == "spherical":
        return SphericalHead(fs_hz=fs_hz)
    p = Path(spec)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", HrirWarning)
        try:
            if p.suffix.lower() == ".sofa":
                head = MeasuredHrirs.from_sofa(p, fs_hz, interpolation=interpolation)
            elif p.suffix.lower() == ".npz":
                head = MeasuredHrirs.from_ku100_npz(p, fs_hz, interpolation=interpolation)
            else:
                raise ValueError(f"--head must be 'spherical', a .sofa file or the KU 100 .npz, got {spec!r}")
        except ValueError as err:
            exit_with_error(str(err))
    for w in caught:
        if issubclass(w.category, HrirWarning):
            console.print(f"warning: {' '.join(str(w.message).split())}", highlight=False, soft_wrap=True,
                          markup=False)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return head


@audio_app.command("calibrate")
def calibrate(
    out: Path = typer.Option(..., help="Model file to write (.npz)."),
    recording: list[str] = typer.Option(
        [], help="Calibration recording as PATH@AZIMUTH_DEG (two-channel audio file, left first); repeat it."
    ),
    head: str = typer.Option("spherical", help="Without --recording: simulate the calibration through this head: "
                             "'spherical', a SOFA file or the KU 100 npz."),
    hrir_interpolation: str = typer.Option("barycentric", help=_INTERPOLATION_HELP),
    signal: Path | None = typer.Option(None, help="Mono source signal for the simulated calibration "
                                       "(default: seeded speech-like signal)."),
    step_deg: float = typer.Option(5.0, help="Azimuth step of the simulated calibration [deg]."),
    fs_hz: float = typer.Option(16000.0, help="Sampling rate of the model [Hz]."),
    bands: int = typer.Option(32, help="Number of gammatone bands."),
    f_min_hz: float = typer.Option(100.0, help="Lowest centre frequency [Hz]."),
    f_max_hz: float = typer.Option(4000.0, help="Highest centre frequency [Hz]."),
) -> None:
    """Calibrate P(tau | S_theta theta) from recordings at known azimuths (or a simulated head) and save it."""
    from ..audio import GammatoneFilterbank, calibrate_sensor_model, read_audio, speech_like_signal
    from ..audio._evaluate import calibrate_from_simulation

    try:
        fb = GammatoneFilterbank(fs_hz, bands, f_min_hz, f_max_hz)
        if recording:
            recs, az = [], []
            for item in recording:
                path, sep, deg = item.rpartition("@")
                if not sep:
                    raise ValueError(f"--recording must be PATH@AZIMUTH_DEG, got {item!r}")
                x, _ = read_audio(path, fs_hz)
                recs.append(x)
                az.append(np.deg2rad(float(deg)))
            model = calibrate_sensor_model(recs, az, fs_hz, fb, source=f"{len(recs)} recordings")
        else:
            sig = read_audio(signal, fs_hz)[0][:, 0] if signal else speech_like_signal(1.5, fs_hz, seed=12345)
            model = calibrate_from_simulation(_head(head, fs_hz, hrir_interpolation), sig, fs_hz, step_deg,
                                              filterbank=fb)
    except ValueError as err:
        exit_with_error(str(err))
    model.save(out)
    console.print(f"wrote {out}: {model.filterbank.n_bands} bands, {model.azimuth_rad.size} azimuths, "
                  f"from {model.source}", markup=False, highlight=False)


@audio_app.command("localize")
def localize_cmd(
    path: Path = typer.Argument(..., help="Two-channel audio file (left, right)."),
    model: Path | None = typer.Option(None, help="Sensor model (.npz); default: the spherical head."),
) -> None:
    """Print the MAP azimuth and the salient sources of a binaural recording."""
    from ..audio import BinauralSensorModel, default_sensor_model, localize, read_audio

    try:
        m = BinauralSensorModel.load(model) if model else default_sensor_model()
        x, fs = read_audio(path, m.fs_hz)
        loc = localize(x, fs, m)
    except ValueError as err:
        exit_with_error(str(err))
    console.print(f"{loc.n_active_frames}/{len(loc.time_s)} active frames, {loc.cues.n_clipped_frames} clipped")
    for a, s in zip(loc.source_azimuths_rad, loc.source_saliency):
        console.print(f"azimuth {np.rad2deg(a):+6.1f} deg (or {np.rad2deg(np.sign(a) * np.pi - a):+6.1f} behind), "
                      f"saliency {s:.3f}")
    if not loc.source_azimuths_rad.size:
        console.print("no evidence (silent, clipped or incoherent audio)")


@audio_app.command("evaluate")
def evaluate(
    head: str = typer.Option("spherical", help="'spherical', a SOFA file or the KU 100 npz."),
    hrir_interpolation: str = typer.Option("barycentric", help=_INTERPOLATION_HELP),
    speech: Path | None = typer.Option(None, help="Mono speech file for the evaluation (default: speech-like, "
                                       "another seed than the calibration)."),
    duration_s: float = typer.Option(2.0, help="Speech per azimuth [s]."),
    step_deg: float = typer.Option(10.0, help="Azimuth step of the sweep -90..90 [deg]."),
    rt60_s: float = typer.Option(0.3, help="Reverberation time of the 6 x 5 x 3 m room [s]."),
    snr_db: float = typer.Option(20.0, help="Sensor SNR [dB]."),
    fs_hz: float = typer.Option(16000.0, help="Sampling rate [Hz]."),
    front_end: str = typer.Option("time", help="Binaural front end: 'time' or 'fft'."),
) -> None:
    """Azimuth MAE over a sweep: planefuse's Bayesian estimator vs pyroomacoustics SRP-PHAT, MUSIC, GCC-PHAT."""
    from ..audio import HEAD_RADIUS_M, ShoeBoxRoom, read_audio, speech_like_signal
    from ..audio._evaluate import (
        SweepScene,
        calibrate_from_simulation,
        evaluate_sweep,
        rendered_azimuths_rad,
        sweep_recordings,
    )

    h = _head(head, fs_hz, hrir_interpolation)
    model = calibrate_from_simulation(h, speech_like_signal(1.5, fs_hz, seed=12345), fs_hz, front_end=front_end)
    n = int(round(duration_s * fs_hz))
    sig = read_audio(speech, fs_hz)[0][:n, 0] if speech else speech_like_signal(duration_s, fs_hz, seed=777)
    az = np.deg2rad(np.arange(-90.0, 90.0 + 1e-9, step_deg))
    rendered = rendered_azimuths_rad(h, az)
    off_deg = np.rad2deg(np.abs(rendered - az))
    if off_deg.max() > 0.01:
        shown = ", ".join(f"{a:g}->{r:.1f}" for a, r, o in zip(np.rad2deg(az), np.rad2deg(rendered), off_deg)
                          if o > 0.01)
        console.print(f"rendered azimuths differ from the sweep's by up to {off_deg.max():.1f} deg [deg]: {shown}; "
                      "the errors below are against the rendered azimuths", highlight=False, markup=False)
    scene = SweepScene(room=ShoeBoxRoom(dims_m=(6.0, 5.0, 3.0), rt60_s=rt60_s), snr_db=snr_db)
    errs = evaluate_sweep(sweep_recordings(sig, az, scene, h, fs_hz), rendered, model, 2 * HEAD_RADIUS_M)
    console.print(units_table(
        f"{h.name}, front end {front_end!r}: {az.size} azimuths, RT60 {rt60_s} s, SNR {snr_db} dB, "
        f"{speech.name if speech else 'speech-like'}",
        ("method", "MAE [deg]", "max [deg]"),
        [(k, f"{np.rad2deg(v.mean()):.2f}", f"{np.rad2deg(v.max()):.1f}") for k, v in errs.items()]))
