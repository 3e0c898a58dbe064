"""planefuse: multi-sensor registration on planes parallel to the ground, Bayesian occupancy fusion and people tracking.

Subpackages
-----------
geometry      rigid transforms, pinhole camera, homographies (IMU and calibration routes)
grid          the plane stack and its grids
registration  image/laser/sound evidence registered on the planes
cli           the ``planefuse`` command line
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("planefuse")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.1.0"

__all__ = ["__version__"]
