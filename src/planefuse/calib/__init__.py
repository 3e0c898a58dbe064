"""Calibration loaders: OpenCV YAML/XML camera files, WILDTRACK XML, EPFL POM ground homographies, Bouguet .mat."""

from ._bouguet import BouguetBoardView, BouguetCalibration, load_bouguet_calibration
from ._epfl import (
    H_WORLD_TOPVIEW_TERRACE,
    EpflBoxes,
    EpflGroundHomography,
    epfl_terrace_pom_stack,
    load_epfl_boxes,
    load_epfl_homography,
)
from ._filestorage import load_opencv_camera, load_opencv_intrinsics, save_opencv_camera
from ._tsai import TERRACE_TSAI, TsaiParams, pinhole_from_tsai, terrace_cameras
from ._wildtrack import WILDTRACK_CAMERAS, load_wildtrack_camera, load_wildtrack_rig

__all__ = [
    "BouguetBoardView",
    "BouguetCalibration",
    "load_bouguet_calibration",
    "H_WORLD_TOPVIEW_TERRACE",
    "EpflBoxes",
    "EpflGroundHomography",
    "epfl_terrace_pom_stack",
    "load_epfl_boxes",
    "load_epfl_homography",
    "load_opencv_camera",
    "load_opencv_intrinsics",
    "save_opencv_camera",
    "TERRACE_TSAI",
    "TsaiParams",
    "pinhole_from_tsai",
    "terrace_cameras",
    "WILDTRACK_CAMERAS",
    "load_wildtrack_camera",
    "load_wildtrack_rig",
]
