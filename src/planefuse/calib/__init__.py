"""Calibration loaders: OpenCV YAML/XML camera files, JSON (VoxelPose/Panoptic), EPFL Tsai XML, ground
homographies, WILDTRACK XML, EPFL POM ground homographies, Bouguet .mat; :func:`load_cameras` reads any of the
formats ``planefuse import`` takes."""

from ._bouguet import BouguetBoardView, BouguetCalibration, load_bouguet_calibration
from ._epfl import (
    H_WORLD_TOPVIEW_TERRACE,
    EpflBoxes,
    EpflGroundHomography,
    epfl_terrace_pom_stack,
    load_epfl_boxes,
    load_epfl_homography,
)
from ._formats import CALIBRATION_FORMATS, LENGTH_UNITS_M, check_metric_scale, load_cameras, load_ground_homographies
from ._ground import camera_from_ground_homography
from ._json import load_json_cameras
from ._tsai import EPFL_TERRACE_TSAI, TsaiCamera, load_tsai_xml, pinhole_from_tsai, tsai_project, write_tsai_xml
from ._filestorage import load_opencv_camera, load_opencv_intrinsics, save_opencv_camera
from ._wildtrack import WILDTRACK_CAMERAS, load_wildtrack_camera, load_wildtrack_rig

__all__ = [
    "CALIBRATION_FORMATS",
    "LENGTH_UNITS_M",
    "check_metric_scale",
    "load_cameras",
    "load_ground_homographies",
    "camera_from_ground_homography",
    "load_json_cameras",
    "EPFL_TERRACE_TSAI",
    "TsaiCamera",
    "load_tsai_xml",
    "pinhole_from_tsai",
    "tsai_project",
    "write_tsai_xml",
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
    "WILDTRACK_CAMERAS",
    "load_wildtrack_camera",
    "load_wildtrack_rig",
]
