"""Named configuration profiles: what real data taught, chosen by what the recording is.

A profile is a set of run-configuration fields with the measurement that chose each value.
``planefuse config init --recording REC`` picks one from the recording (:func:`profile_for_recording`) and
writes its values into the configuration, each with its reason as a comment; a user never copies settings out of
a script.

- ``simulated``: the library's own defaults (:class:`planefuse.pipeline.SystemParams`), chosen on simulated seeds
  1-3. ``planefuse demo`` is ``planefuse simulate`` + ``config init`` + ``run`` with it, byte for byte.
- ``real-video``: real camera video (``planefuse import``). Chosen on the EPFL terrace (terrace1, cameras c0 + c1,
  360 x 288 px at 25 Hz, outdoor, automatic exposure) on frames 0-1499 only; frames 1500-2999 are reported
  (docs/results.md). ``scripts/terrace.yaml`` runs exactly these values (a test pins it).

A new setting found on real data (e.g. a person detector's) is added to :data:`REAL_VIDEO` with its measurement.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["FittedConfig", "Profile", "ProfileSetting", "PROFILES", "REAL_VIDEO", "SIMULATED",
           "config_for_recording", "profile_for_recording", "profile_changes"]


@dataclass(frozen=True)
class ProfileSetting:
    """One field of a profile.

    Attributes
    ----------
    field : str
        Dotted run-configuration field, e.g. ``sensors.cameras.var_threshold``.
    value : Any
        Its value (YAML-compatible: list, float, str, bool or None).
    why : str
        The measurement that chose it (frames or seeds, scores, what it was compared with).
    """

    field: str
    value: Any
    why: str


@dataclass(frozen=True)
class Profile:
    """A named set of run-configuration fields (:class:`ProfileSetting`) written by ``planefuse config init``.

    Attributes
    ----------
    name : str
    description : str
        One line: what recordings it is for and where it was measured.
    settings : tuple of ProfileSetting
        Fields that differ from the configuration's defaults (the library's); empty = the defaults.
    """

    name: str
    description: str
    settings: tuple[ProfileSetting, ...] = ()

    def changes(self) -> dict:
        """The settings as a nested mapping (``{"sensors": {"cameras": {"var_threshold": 900}}}``)."""
        out: dict = {}
        for s in self.settings:
            *heads, last = s.field.split(".")
            node = out
            for h in heads:
                node = node.setdefault(h, {})
            node[last] = s.value
        return out

    def notes(self) -> dict[str, str]:
        """Field path -> the measurement that chose its value."""
        return {s.field: s.why for s in self.settings}


_TERRACE = "EPFL terrace c0 + c1, frames 0-1499"

#: The library's defaults, chosen on simulated seeds 1-3 (docs/results.md): what ``planefuse demo`` runs.
SIMULATED = Profile("simulated", "the library's defaults, chosen on simulated recordings (seeds 1-3)")

#: Real camera video: the settings chosen on the EPFL terrace, frames 0-1499 (every 5th or 10th frame).
REAL_VIDEO = Profile(
    "real-video",
    f"real camera video; chosen on the {_TERRACE} (held-out frames 1500-2999: docs/results.md)",
    (
        ProfileSetting("sensors.cameras.foreground_method", "knn", "OpenCV's KNN subtractor on real video"),
        ProfileSetting("sensors.cameras.var_threshold", 900.0,
                       f"KNN dist2Threshold 900 (OpenCV's 400) with a 9 px closing: fewer speckle ghosts, fuller "
                       f"people ({_TERRACE} every 10th, filtered MODA 0.639 -> 0.742 at 0.5 m)"),
        ProfileSetting("sensors.cameras.close_px", 9, "with var_threshold 900 (same measurement)"),
        ProfileSetting("sensors.cameras.gain_compensation", True,
                       "real cameras' automatic exposure and clouds change the whole image's brightness"),
        ProfileSetting("sensors.cameras.gain_blocks", [1, 1], "one gain per channel"),
        ProfileSetting("sensors.cameras.primed_rate", "automatic",
                       "the empty scene is an estimate (`planefuse import --background-median-s 20`): a person "
                       "standing still may be in it, so the models go on learning at OpenCV's fast start. "
                       f"{_TERRACE}, cold start at frame 500 / 750 / 1000, filtered MODA 0.5 m 0.778 / 0.711 / 0.658 "
                       "with the estimate against 0.745 / 0.629 / 0.553 without"),
        ProfileSetting("sensors.cameras.plate_frames", 30,
                       f"the estimate weighs as 30 frames of the fast start; {_TERRACE} every 5th from frame 0, "
                       "filtered MODA 0.5 / 1.0 m, MOTA, IDF1 0.764 / 0.880, 0.781, 0.889 against 0.761 / 0.873, "
                       "0.766, 0.881 with 10"),
        ProfileSetting("sensors.cameras.shadow_likelihood", 0.5,
                       "dark clothes on a light floor are labelled shadow: unknown, not background"),
        ProfileSetting("sensors.cameras.selective_update", False,
                       "OpenCV's blind update: keeping found people out of the model lost on a cold start "
                       "(EPFL terrace frames 1000-1499 from a cold start, filtered MOTA 0.358 against 0.480)"),
        ProfileSetting("sensors.cameras.sensor_model", "generative",
                       "few cameras: the generative model explains each image by people, removing the ghosts where "
                       "two views' silhouettes cross (terrace filtered MODA 0.58 against -3.0 per cell)"),
        ProfileSetting("sensors.cameras.generative_sigma", 0.005, f"chosen on the {_TERRACE}"),
        ProfileSetting("sensors.cameras.generative_people_per_m2", 0.05, f"chosen on the {_TERRACE}"),
        ProfileSetting("sensors.cameras.generative_evidence_prior", "detection",
                       "the filter's evidence consistent with the per-frame detector; every 5th frame, filtered "
                       "MODA 0.5 / 1.0 m, MOTA, IDF1 0.763 / 0.877, 0.784, 0.861 against 0.765 / 0.864, 0.750, "
                       "0.783 with even odds"),
        ProfileSetting("sensors.cameras.generative_detection_mass", 0.6,
                       "expected people within 0.2 m for a per-frame detection; frames 0-1499 cold, filtered "
                       "MODA 0.5 / 1.0 m 0.761 / 0.873 against 0.753 / 0.867 at 0.5 (MOTA, IDF1 within 0.01)"),
        ProfileSetting("sensors.cameras.generative_track_prior_ratio", 2.0,
                       "twice the prior near a confirmed track's prediction; frames 0-1499 cold, filtered MODA "
                       "0.5 / 1.0 m, MOTA, IDF1 0.779 / 0.885, 0.779, 0.888 against 0.761 / 0.873, 0.766, 0.881 "
                       "without (1000-1499 cold: MOTA 0.719 against 0.686)"),
        ProfileSetting("sensors.cameras.generative_track_prior_radius_m", 0.5,
                       "with generative_track_prior_ratio (0.7 and 1.0 m: docs/results.md)"),
        ProfileSetting("models.filter.camera_correlation_s", 0.2,
                       "every 5th frame (0.2 s apart) a whole observation: filtered MODA / MOTA / IDF1 0.765 / "
                       "0.749 / 0.784 against 0.703 / 0.672 / 0.711 at the library's 0.5 s"),
        ProfileSetting("models.detection.column_threshold", 2.0,
                       "mean capped log-odds per body plane of a person's column (2.0 against 3.0 and 1.5)"),
        ProfileSetting("models.detection.position_std_m", 0.2,
                       "real detections at 5 Hz are noisier than simulated ones: filtered MOTA / IDF1 0.749 / "
                       "0.784 against 0.737 / 0.778 at 0.1 m and 0.721 / 0.779 at 0.3 m"),
        ProfileSetting("models.detection.support_threshold", None,
                       "no support of confirmed tracks by weak evidence: filtered MOTA / IDF1 0.784 / 0.861 "
                       "against 0.754 / 0.801 at the library's 1.0"),
        ProfileSetting("models.detection.velocity_decorrelation", False,
                       "the simulated seeds' decorrelation cost identities: filtered MOTA / IDF1 0.789 / 0.863 "
                       "without, 0.787 / 0.714 with"),
        ProfileSetting("models.detection.position_from_step_evidence", True,
                       "frames 0-1499 cold, filtered MOTA / IDF1 0.762 / 0.806 against 0.755 / 0.754 with the "
                       "filter's mode"),
        ProfileSetting("models.detection.birth_exclusion_m", 1.5,
                       "the filter's smeared blobs start duplicates beside tracked people; frames 0-1499 cold, "
                       "filtered MOTA / IDF1 0.766 / 0.882 against 0.762 / 0.806 (1.0 m: IDF1 0.855)"),
        ProfileSetting("models.detection.max_coast_report", 1,
                       "a track without a cluster is reported for one step (with birth_exclusion_m)"),
        ProfileSetting("models.detection.appearance_weight", 16.0,
                       "each camera's colours of a person in the tracker's pairing cost (docs/identities.md); with "
                       "re-identification, frames 1000-1499 cold, filtered MOTA / IDF1 0.725 / 0.858 against 0.719 / "
                       "0.804 without (frames 0-1499 and 500-1499 cold: unchanged)"),
        ProfileSetting("models.detection.reid_max_s", 5.0,
                       "a track lost for up to 5 s takes back its person by colours (same measurement)"),
        ProfileSetting("models.detection.stitch", True,
                       "the offline pass after a recording's run (tracks_stitched.csv; a live run stays online): "
                       "tracklets cut where their colours change and joined across gaps. Cold starts at frames 0 / "
                       "500 / 1000 every 5th, IDF1 0.888 / 0.899 / 0.804 -> 0.908 / 0.922 / 0.868, MOTA 0.779 / "
                       "0.804 / 0.719 -> 0.819 / 0.846 / 0.735; with the YOLOX detector IDF1 0.890 / 0.898 / 0.861 -> "
                       "0.921 / 0.926 / 0.884, MOTA 0.783 / 0.800 / 0.731 -> 0.842 / 0.854 / 0.771; every 15th frame "
                       "(1.7 Hz, where the tracker exchanges people) IDF1 0.565 -> 0.826, identity switches 7 -> 2"),
        ProfileSetting("models.detection.stitch_fill_gap_s", 4.0,
                       "with stitch on: gaps up to 4 s within one identity filled on the straight line; frames "
                       "0-1499 (cold starts at 0, 500, 1000 every 5th frame, at 0 every 10th; YOLOX front end, "
                       "appearance on), stitched IDF1 / MOTA 0.884 / 0.773 against 0.874 / 0.760 unfilled (2 s: "
                       "0.878 / 0.765, 8 s: 0.879 / 0.763)"),
        ProfileSetting("models.detection.stitch_smooth_s", 0.6,
                       "with stitch on: each identity's positions smoothed by a 0.6 s Gaussian in time; same frames, "
                       "IDF1 / MOTA 0.903 / 0.810 against 0.884 / 0.773 unsmoothed (0.4 s: 0.894 / 0.794, 1.0 s: "
                       "0.891 / 0.786)"),
    ),
)

#: Every named profile.
PROFILES: dict[str, Profile] = {p.name: p for p in (SIMULATED, REAL_VIDEO)}

#: The manifest's ``source`` of a recording written by ``planefuse simulate``.
SIMULATED_SOURCE_PREFIX = "planefuse simulate"


def profile_for_recording(rec) -> tuple[Profile, str]:
    """The profile for a recording, and why.

    Parameters
    ----------
    rec : planefuse.io.Recording
        Its ``source`` (``scene.yaml``'s, which ``planefuse simulate`` and ``planefuse import`` write) and cameras.

    Returns
    -------
    (Profile, str)
        :data:`SIMULATED` for a recording ``planefuse simulate`` wrote (its ``source``) or one without cameras,
        :data:`REAL_VIDEO` for any other recording with cameras (``planefuse import`` of videos or image folders);
        the reason in words.
    """
    source = rec.source or ""
    if source.startswith(SIMULATED_SOURCE_PREFIX):
        return SIMULATED, f"the recording is simulated (source: {source})"
    if not rec.camera_streams:
        return SIMULATED, "the recording has no cameras (the real-video profile sets cameras only)"
    what = " ".join(source.split()[:2]) or "no source recorded"
    return REAL_VIDEO, f"the recording's cameras are real video ({what})"


def profile_changes(name: str) -> dict:
    """The nested configuration changes of the profile ``name`` (a key of :data:`PROFILES`)."""
    if name not in PROFILES:
        raise ValueError(f"unknown profile {name!r}: use one of {', '.join(PROFILES)}")
    return PROFILES[name].changes()


@dataclass(frozen=True)
class FittedConfig:
    """A run configuration fitted to a recording by :func:`config_for_recording`.

    Attributes
    ----------
    config : RunConfig
    profile : Profile
        The profile written into it.
    messages : tuple of str
        What was chosen and why (the profile, a proposed monitored area), to show the user.
    """

    config: Any
    profile: Profile
    messages: tuple[str, ...]


def config_for_recording(rec, profile: str | None = None, person_model: str | None = None) -> FittedConfig:
    """The run configuration ``planefuse config init --recording`` writes for a recording.

    - sensors: the library's, less those the recording lacks;
    - the profile (``profile``, or :func:`profile_for_recording`'s choice): ``simulated`` leaves every other field
      at the library's default (the plane heights, and the grid as the recording's room less
      ``planes.wall_margin_m``), so that ``planefuse demo`` and ``simulate`` + ``config init`` + ``run`` are one
      run; ``real-video`` writes its settings, the recording's suggested plane heights and its monitored area
      (``room_xy_m``, which ``planefuse import --room`` sets) as the grid;
    - a recording without a monitored area gets the box around the ground at least two cameras see
      (:func:`planefuse.registration.proposed_area_xy_m`), and a message saying so.

    Parameters
    ----------
    rec : planefuse.io.Recording
    profile : str or None
        A key of :data:`PROFILES`; None = chosen from the recording.
    person_model : str or None
        A YOLOX ONNX file (the user's download): the cameras run it as their person detector (``person_detector:
        yolox``) at the library's settings for its boxes (docs/cameras.md, "Person detector"); written as given.

    Raises
    ------
    ValueError
        An unknown profile. (A recording without a monitored area whose cameras share no ground gets a
        configuration without one, ``planes.x_range_m`` null, and a message asking for it.)
    """
    from ..registration import proposed_area_xy_m
    from ._load import config_from_dict
    from ._models import RunConfig

    messages: list[str] = []
    if profile is None:
        chosen, why = profile_for_recording(rec)
    elif profile in PROFILES:
        chosen, why = PROFILES[profile], "asked for"
    else:
        raise ValueError(f"unknown profile {profile!r}: use one of {', '.join(PROFILES)}")
    messages.append(f"profile {chosen.name}: {why}; {chosen.description}")
    base = RunConfig(recording=rec.root if rec.root is not None else Path("."))
    present = {"cameras": bool(rec.camera_streams), "laser": bool(rec.lasers), "sound": bool(rec.audio)}
    data = base.model_dump(mode="json", exclude_unset=True)
    data["recording"] = str(base.recording)
    sensors = {k: {"enabled": getattr(base.sensors, k).enabled and on} for k, on in present.items()}
    changes: dict = {"sensors": sensors}
    area = rec.room_xy_m
    if area is None:
        area = proposed_area_xy_m(rec.cameras) if rec.camera_streams else None
        if area is None:
            messages.append("the recording has no monitored area (room_xy_m) and no ground is seen by two of its "
                            "cameras: set planes.x_range_m and planes.y_range_m in the configuration (or import "
                            "again with --room X0,X1,Y0,Y1)")
        else:
            messages.append(f"monitored area proposed from the ground at least two cameras see (people >= 20 px "
                            f"tall): x {area[0]:g}..{area[1]:g} m, y {area[2]:g}..{area[3]:g} m; check it on the "
                            "pictures of `planefuse check --figures`, and change planes.x_range_m / y_range_m where "
                            "it should differ")
    planes: dict = {}
    if area is not None and (chosen.name != SIMULATED.name or rec.room_xy_m is None):
        planes.update(x_range_m=[area[0], area[1]], y_range_m=[area[2], area[3]])
    if chosen.name != SIMULATED.name:
        planes["heights_m"] = list(rec.planes_heights_m)
    if planes:
        changes["planes"] = planes
    data = _merged(_merged(data, changes), chosen.changes())
    if person_model is not None:
        if not rec.camera_streams:
            raise ValueError("a person model was given but the recording has no cameras")
        data = _merged(data, {"sensors": {"cameras": {"person_detector": "yolox", "person_model": str(person_model)}}})
        messages.append(f"person detector: YOLOX {person_model}, its boxes as evidence on the planes (docs/detector.md)")
    return FittedConfig(config_from_dict(data, f"profile {chosen.name}"), chosen, tuple(messages))


def _merged(base: dict, changes: dict) -> dict:
    out = dict(base)
    for k, v in changes.items():
        out[k] = _merged(out.get(k) or {}, v) if isinstance(v, dict) else v
    return out
