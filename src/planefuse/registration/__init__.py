"""Registration of sensor data onto the plane stack."""

from ._lookup import ImagePlaneLookup

__all__ = ["ImagePlaneLookup"]
