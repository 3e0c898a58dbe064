"""Tsai camera model (R. Tsai 1987, R. Willson's implementation) as EPFL CVLab distributes it, and its
conversion to planefuse's :class:`PinholeCamera` with OpenCV distortion.

The model, with world points ``X_w`` in the calibration's length unit (EPFL: millimetres, ground Z = 0):

* ``X_c = R X_w + T``, ``R = Rz(rz) Ry(ry) Rx(rx)`` [rad];
* undistorted sensor coordinates [mm]: ``X_u = f X_c / Z_c``, ``Y_u = f Y_c / Z_c``;
* radial distortion, *distorted to undistorted*: ``X_u = X_d (1 + kappa1 r^2)``, ``r^2 = X_d^2 + Y_d^2`` [mm^2];
* pixels: ``u = sx X_d / dpx + Cx``, ``v = Y_d / dpy + Cy`` (``dpx = dx ncx / nfx`` when the file omits it).

EPFL's XML file per camera::

    <Camera name="c0">
      <Geometry width="720" height="576" ncx="576" nfx="576" dx="0.023" dy="0.023" dpx="0.023" dpy="0.023"/>
      <Intrinsic focal="20.16192" kappa1="5.720865e-04" cx="366.514507" cy="305.832552" sx="1"/>
      <Extrinsic tx="-4844.19" ty="551.09" tz="4966.74" rx="1.9007" ry="0.4973" rz="0.1841"/>
    </Camera>

OpenCV's radial model runs the other way (undistorted -> distorted, ``x_d = x_u (1 + k1 r^2 + k2 r^4 + k3 r^6)``),
so :func:`pinhole_from_tsai` fits ``k1, k2, k3`` to the exact inverse of Tsai's model over the image and reports
the largest pixel error of the fit (hundredths of a pixel for EPFL's cameras).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry._camera import CameraIntrinsics, PinholeCamera
from ..geometry._transforms import invert_transform, transform_from_rotation_translation
from ._filestorage import calib_error

__all__ = [
    "TsaiCamera",
    "EPFL_TERRACE_TSAI",
    "load_tsai_xml",
    "write_tsai_xml",
    "tsai_project",
    "pinhole_from_tsai",
]


@dataclass(frozen=True)
class TsaiCamera:
    """One camera of the Tsai model (see the module docstring). Lengths in the calibration's unit
    (``tx, ty, tz``; EPFL: mm), sensor sizes in mm, angles in radians, pixels of a ``width_px`` x ``height_px``
    image."""

    width_px: int
    height_px: int
    focal_mm: float
    kappa1_per_mm2: float
    cx_px: float
    cy_px: float
    sx: float
    dpx_mm: float
    dpy_mm: float
    rx_rad: float
    ry_rad: float
    rz_rad: float
    tx: float
    ty: float
    tz: float
    ncx: float = 0.0
    nfx: float = 0.0
    name: str = "camera"

    @property
    def R_cam_world(self) -> np.ndarray:
        """``Rz(rz) Ry(ry) Rx(rx)`` (3, 3): world -> camera rotation."""
        ca, sa = np.cos(self.rx_rad), np.sin(self.rx_rad)
        cb, sb = np.cos(self.ry_rad), np.sin(self.ry_rad)
        cg, sg = np.cos(self.rz_rad), np.sin(self.rz_rad)
        Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
        Ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
        Rz = np.array([[cg, -sg, 0], [sg, cg, 0], [0, 0, 1]])
        return Rz @ Ry @ Rx

    @property
    def t_cam_world(self) -> np.ndarray:
        """``T`` (3,) in the calibration's length unit."""
        return np.array([self.tx, self.ty, self.tz], dtype=float)


def _camera(name: str, f, k1, cx, cy, rx, ry, rz, tx, ty, tz) -> TsaiCamera:
    return TsaiCamera(720, 576, f, k1, cx, cy, 1.0, 0.023, 0.023, rx, ry, rz, tx, ty, tz, 576.0, 576.0, name)


#: EPFL terrace cameras c0..c3 (720x576 px, world in mm, ground Z = 0) as reported in several public loaders; see
#: ``../shared/data/epfl_pom/SOURCE.md`` ("Terrace Tsai model"). EPFL distributes them as ``terrace-tsai`` XML
#: files; :func:`write_tsai_xml` writes that layout.
EPFL_TERRACE_TSAI: dict[str, TsaiCamera] = {
    "c0": _camera("c0", 20.161920, 5.720865e-4, 366.514507, 305.832552, 1.9007833770, 0.49730769727,
                  0.18415452559, -4844.1913843, 551.09448682, 4966.7438357),
    "c1": _camera("c1", 19.529144, 5.184242e-4, 360.228130, 255.166919, 1.9347282363, -0.70418616982,
                  -0.23783238362, -65.433635, 1594.811988, 2113.640844),
    "c2": _camera("c2", 19.903218, 3.511557e-4, 355.506436, 241.205640, -1.8289537286, 0.37748154985,
                  3.0218614321, 1978.2813424, -940.27627332, 12397.750058),
    "c3": _camera("c3", 20.047015, 4.347668e-4, 349.154019, 245.786168, -1.8418460467, -0.46728290805,
                  -3.0205552749, 4673.7509054, -25.743341287, 8415.5952460),
}

_FIELDS = {
    "Geometry": {"width": "width_px", "height": "height_px", "ncx": "ncx", "nfx": "nfx", "dpx": "dpx_mm",
                 "dpy": "dpy_mm"},
    "Intrinsic": {"focal": "focal_mm", "kappa1": "kappa1_per_mm2", "cx": "cx_px", "cy": "cy_px", "sx": "sx"},
    "Extrinsic": {"tx": "tx", "ty": "ty", "tz": "tz", "rx": "rx_rad", "ry": "ry_rad", "rz": "rz_rad"},
}


def load_tsai_xml(path, *, name: str | None = None) -> TsaiCamera:
    """Read one camera of EPFL's Tsai XML layout (module docstring).

    ``dpx``/``dpy`` default to ``dx * ncx / nfx`` and ``dy`` when absent; ``sx`` defaults to 1.

    Raises
    ------
    ValueError
        ``<file>: field '<Element.attribute>': ...`` for a missing file, malformed XML, a missing element or
        attribute, a non-numeric or non-finite value, or a non-positive image size, focal length or pixel pitch.
    """
    p = Path(path)
    if not p.is_file():
        raise calib_error(p, "<file>", "no such file")
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as exc:
        raise calib_error(p, "<file>", f"not well-formed XML ({exc})") from None
    if root.tag != "Camera":
        cam = root.find(".//Camera")
        if cam is None:
            raise calib_error(p, "Camera", f"no <Camera> element (root is <{root.tag}>)")
        root = cam

    def num(elem: str, attr: str, default: float | None = None) -> float:
        e = root.find(elem)
        text = None if e is None else e.get(attr)
        if text is None:
            if default is not None:
                return default
            raise calib_error(p, f"{elem}.{attr}", "missing")
        try:
            v = float(text)
        except ValueError:
            raise calib_error(p, f"{elem}.{attr}", f"non-numeric value {text!r}") from None
        if not np.isfinite(v):
            raise calib_error(p, f"{elem}.{attr}", f"non-finite value {text!r}")
        return v

    ncx, nfx = num("Geometry", "ncx", 1.0), num("Geometry", "nfx", 1.0)
    dx = num("Geometry", "dx", np.nan)
    dy = num("Geometry", "dy", np.nan)
    dpx = num("Geometry", "dpx", dx * ncx / nfx if np.isfinite(dx) else None)
    dpy = num("Geometry", "dpy", dy if np.isfinite(dy) else None)
    values = {}
    for elem, attrs in _FIELDS.items():
        for attr, field in attrs.items():
            if field in ("dpx_mm", "dpy_mm"):
                continue
            values[field] = num(elem, attr, {"sx": 1.0, "ncx": ncx, "nfx": nfx}.get(attr))
    for field, what in (("width_px", "Geometry.width"), ("height_px", "Geometry.height"), ("focal_mm", "Intrinsic.focal")):
        if values[field] <= 0:
            raise calib_error(p, what, f"must be positive, got {values[field]}")
    if dpx <= 0 or dpy <= 0:
        raise calib_error(p, "Geometry.dpx", f"pixel pitch must be positive, got dpx={dpx}, dpy={dpy}")
    values["width_px"], values["height_px"] = int(values["width_px"]), int(values["height_px"])
    return TsaiCamera(dpx_mm=dpx, dpy_mm=dpy, name=name or root.get("name") or p.stem, **values)


def write_tsai_xml(path, cam: TsaiCamera) -> None:
    """Write ``cam`` in EPFL's Tsai XML layout (17 significant digits: :func:`load_tsai_xml` reads it back exactly)."""
    root = ET.Element("Camera", name=cam.name)
    for elem, attrs in _FIELDS.items():
        ET.SubElement(root, elem, {a: repr(float(getattr(cam, f))) if f not in ("width_px", "height_px")
                                   else str(getattr(cam, f)) for a, f in attrs.items()})
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)


def tsai_project(cam: TsaiCamera, p_world) -> np.ndarray:
    """Project world points (N, 3) [calibration unit] to pixels (N, 2) with Tsai's own model (reference).

    The distorted radius solves ``r_u = r_d (1 + kappa1 r_d^2)`` by Newton's method (monotonic for
    ``kappa1 >= 0``); points behind the camera are NaN.
    """
    p = np.asarray(p_world, dtype=float).reshape(-1, 3)
    pc = p @ cam.R_cam_world.T + cam.t_cam_world
    with np.errstate(divide="ignore", invalid="ignore"):
        xu = cam.focal_mm * pc[:, :2] / pc[:, 2:3]
    ru = np.linalg.norm(xu, axis=1)
    rd = ru.copy()
    for _ in range(50):
        rd = rd - (rd * (1 + cam.kappa1_per_mm2 * rd**2) - ru) / (1 + 3 * cam.kappa1_per_mm2 * rd**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(ru > 0, rd / ru, 1.0)
    xd = xu * scale[:, None]
    uv = np.c_[cam.sx * xd[:, 0] / cam.dpx_mm + cam.cx_px, xd[:, 1] / cam.dpy_mm + cam.cy_px]
    uv[pc[:, 2] <= 0] = np.nan
    return uv


def pinhole_from_tsai(cam: TsaiCamera, *, metres_per_unit: float, width_px: int | None = None,
                      height_px: int | None = None, name: str | None = None) -> tuple[PinholeCamera, float]:
    """The equivalent :class:`PinholeCamera` (world in metres, OpenCV ``k1 k2 0 0 k3``) of a Tsai camera.

    Parameters
    ----------
    cam : TsaiCamera
    metres_per_unit : float
        Length unit of ``tx, ty, tz`` in metres (EPFL: 0.001).
    width_px, height_px : int, optional
        Size of the images the camera is used with; the calibration's pixels are scaled to it (EPFL's 720x576
        calibration for its 360x288 videos: 0.5), pixel centres kept on pixel centres
        (``u' = s (u + 0.5) - 0.5``). Both sizes must scale by the same factor.
    name : str, optional
        Defaults to ``cam.name``.

    Returns
    -------
    (PinholeCamera, float)
        The camera and the largest pixel error of the fitted OpenCV distortion over the image (in the output
        pixels).

    Raises
    ------
    ValueError
        A bad ``metres_per_unit``, image sizes that do not scale uniformly, or a distortion the OpenCV model
        cannot follow over the image (fit error above 0.5 px).
    """
    if not (np.isfinite(metres_per_unit) and metres_per_unit > 0):
        raise ValueError(f"metres_per_unit must be a positive number, got {metres_per_unit}")
    w = cam.width_px if width_px is None else int(width_px)
    h = cam.height_px if height_px is None else int(height_px)
    s = w / cam.width_px
    if abs(h / cam.height_px - s) > 1e-9:
        raise ValueError(f"camera {cam.name!r}: images of {w}x{h} px are not a uniform scaling of the calibration's "
                         f"{cam.width_px}x{cam.height_px} px")
    fx, fy = cam.sx * cam.focal_mm / cam.dpx_mm, cam.focal_mm / cam.dpy_mm
    K = np.array([[fx, 0.0, cam.cx_px], [0.0, fy, cam.cy_px], [0.0, 0.0, 1.0]])
    # Distortion in normalised coordinates: x_u = x_d (1 + k r_d^2), k = kappa1 f^2 (dimensionless).
    k = cam.kappa1_per_mm2 * cam.focal_mm**2
    corners = np.array([[0, 0], [cam.width_px, 0], [0, cam.height_px], [cam.width_px, cam.height_px]], float)
    rd_max = np.max(np.hypot((corners[:, 0] - cam.cx_px) / fx, (corners[:, 1] - cam.cy_px) / fy))
    rd = np.linspace(0.0, 1.05 * rd_max, 400)
    ru = rd * (1 + k * rd**2)
    if np.any(np.diff(ru) <= 0):
        raise ValueError(f"camera {cam.name!r}: Tsai distortion kappa1={cam.kappa1_per_mm2} folds inside the image")
    # x_d / x_u = rd / ru = 1 + k1 ru^2 + k2 ru^4 + k3 ru^6, least squares in pixels (weight ru).
    g = np.where(ru > 0, rd / np.where(ru > 0, ru, 1), 1.0)
    A = np.stack([ru**2, ru**4, ru**6], axis=1) * ru[:, None]
    coef, *_ = np.linalg.lstsq(A, (g - 1) * ru, rcond=None)
    err_px = float(np.max(np.abs(A @ coef - (g - 1) * ru)) * max(fx, fy) * s)
    if err_px > 0.5:
        raise ValueError(f"camera {cam.name!r}: OpenCV's radial model cannot follow Tsai kappa1={cam.kappa1_per_mm2} "
                         f"over the image (fit error {err_px:.2f} px)")
    S = np.array([[s, 0.0, 0.5 * s - 0.5], [0.0, s, 0.5 * s - 0.5], [0.0, 0.0, 1.0]])
    intr = CameraIntrinsics(S @ K, w, h, np.array([coef[0], coef[1], 0.0, 0.0, coef[2]]))
    T_cam_world = transform_from_rotation_translation(cam.R_cam_world, cam.t_cam_world * metres_per_unit)
    return PinholeCamera(intr, invert_transform(T_cam_world), name or cam.name), err_px

