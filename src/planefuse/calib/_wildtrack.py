"""WILDTRACK calibration: OpenCV XML intrinsics (with distortion) and rvec/tvec extrinsics in centimetres.

World frame of the data set: ground plane Z = 0, Z up, centimetres; planefuse converts it to metres.
``X_cam = R(rvec) X_world + tvec`` (OpenCV convention). Images are 1920x1080.
"""

from __future__ import annotations

from pathlib import Path

from ..geometry._camera import PinholeCamera
from ._filestorage import calib_error, intrinsics_from_filestorage, open_filestorage, T_world_cam_from_filestorage

__all__ = ["WILDTRACK_CAMERAS", "load_wildtrack_camera", "load_wildtrack_rig"]

#: Image name -> calibration name (from the data set's ``generate_rect.sh``).
WILDTRACK_CAMERAS = {
    "C1": "CVLab1",
    "C2": "CVLab2",
    "C3": "CVLab3",
    "C4": "CVLab4",
    "C5": "IDIAP1",
    "C6": "IDIAP2",
    "C7": "IDIAP3",
}

_CM = 0.01  # metres per WILDTRACK world unit


def load_wildtrack_camera(
    intrinsic_xml, extrinsic_xml, *, name: str | None = None, width_px: int = 1920, height_px: int = 1080
) -> PinholeCamera:
    """One WILDTRACK camera with distortion, placed in the world in metres.

    Parameters
    ----------
    intrinsic_xml : str or Path
        ``intr_<cam>.xml`` with ``camera_matrix`` (3x3, px) and ``distortion_coefficients`` (k1 k2 p1 p2 k3).
    extrinsic_xml : str or Path
        ``extr_<cam>.xml`` with ``rvec`` (Rodrigues, rad) and ``tvec`` (cm), world -> camera.
    name : str, optional
        Camera name (defaults to the calibration name, e.g. ``CVLab1``).
    width_px, height_px : int
        Image size [px] (the XML does not store it).

    Raises
    ------
    ValueError
        Naming the file and the field that is missing or malformed.
    """
    fs = open_filestorage(intrinsic_xml)
    try:
        intr = intrinsics_from_filestorage(fs, intrinsic_xml, width_px, height_px)
    finally:
        fs.release()
    fs = open_filestorage(extrinsic_xml)
    try:
        T = T_world_cam_from_filestorage(fs, extrinsic_xml, _CM)
    finally:
        fs.release()
    if T is None:
        raise calib_error(extrinsic_xml, "rvec", "missing")
    default = Path(intrinsic_xml).stem.removeprefix("intr_")
    return PinholeCamera(intr, T, name or default)


def load_wildtrack_rig(root) -> dict[str, PinholeCamera]:
    """All seven cameras of a WILDTRACK folder (``intrinsic/``, ``extrinsic/``), keyed by image name C1..C7.

    Each camera is named after its image (``C1``...) and uses ``intrinsic/intr_<calib>.xml`` and
    ``extrinsic/extr_<calib>.xml`` with the mapping :data:`WILDTRACK_CAMERAS`.
    """
    root = Path(root)
    if not (root / "intrinsic").is_dir() or not (root / "extrinsic").is_dir():
        held = sorted(p.name for p in root.iterdir())[:10] if root.is_dir() else None
        raise ValueError(f"{root}: not a WILDTRACK folder: needs intrinsic/ and extrinsic/ "
                         + (f"(it holds {held})" if held is not None else "(no such folder)"))
    return {
        img: load_wildtrack_camera(
            root / "intrinsic" / f"intr_{cal}.xml", root / "extrinsic" / f"extr_{cal}.xml", name=img
        )
        for img, cal in WILDTRACK_CAMERAS.items()
    }
