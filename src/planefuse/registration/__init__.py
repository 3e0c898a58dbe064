"""Registration of sensor data onto the plane stack."""

from ._attitude import (
    ATTITUDE_SOURCES,
    AttitudeTrack,
    CameraRegistration,
    RegistrationParams,
    ground_reprojection_error_m,
    gyro_bias_at_rest,
    pixel_shift_px,
    rest_at_start_s,
)
from ._coverage import (
    MIN_PERSON_PX,
    PERSON_HEIGHT_M,
    camera_view_findings,
    cameras_per_cell,
    max_useful_range_m,
    proposed_area_xy_m,
)
from ._lookup import ImagePlaneLookup

__all__ = ["ATTITUDE_SOURCES", "AttitudeTrack", "CameraRegistration", "ImagePlaneLookup", "MIN_PERSON_PX",
           "PERSON_HEIGHT_M", "RegistrationParams", "camera_view_findings", "cameras_per_cell",
           "ground_reprojection_error_m", "gyro_bias_at_rest", "max_useful_range_m", "pixel_shift_px",
           "proposed_area_xy_m", "rest_at_start_s"]
