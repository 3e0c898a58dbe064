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
from ._lookup import ImagePlaneLookup

__all__ = ["ATTITUDE_SOURCES", "AttitudeTrack", "CameraRegistration", "ImagePlaneLookup", "RegistrationParams",
           "ground_reprojection_error_m", "gyro_bias_at_rest", "pixel_shift_px", "rest_at_start_s"]
