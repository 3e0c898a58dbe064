"""Cameras whose attitude changes over time: a swaying mast, a bump that stays, a pan sweep.

A camera rotates about its optical centre (a pan-tilt head, a camera knocked on its mount; a mast's sway
is modelled as the rotation it gives the camera, its few centimetres of translation neglected). Its
attitude at time t is the calibrated (rest) attitude turned by every motion of its spec, in list order::

    R_world_cam(t) = Rot(axis_K, angle_K(t)) @ ... @ Rot(axis_1, angle_1(t)) @ R_world_cam0

with the axes fixed in the world: ``"pan"`` the vertical (world z), ``"tilt"`` the rest camera's x axis
(right), ``"roll"`` its optical axis. The same function drives the rendered frames
(:class:`~planefuse.sim.CameraRenderer`) and the IMU (:func:`~planefuse.sim.simulate_imu`: the gyroscope
measures the body rate of this attitude, the accelerometer gravity seen in it).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.spatial.transform import Rotation

__all__ = ["CameraMotionSpec", "R_world_cam_at", "omega_cam_rad_s_at", "max_motion_deg"]


class CameraMotionSpec(BaseModel):
    """One motion of a camera about its optical centre (angles in degrees, times in seconds).

    ``kind``:

    * ``"sway"``: ``angle(t) = amplitude_deg sin(2 pi (t - start_s) / period_s)`` for t >= start_s
      (a mast in the wind; default axis tilt);
    * ``"bump"``: a step of ``amplitude_deg`` over ``duration_s`` from ``start_s`` (raised-cosine
      profile), which stays (a knocked camera; default axis tilt);
    * ``"pan"``: a back-and-forth sweep ``amplitude_deg sin(2 pi (t - start_s) / period_s)`` about the
      vertical (a pan head re-aiming; default axis pan).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    kind: Literal["sway", "bump", "pan"]
    amplitude_deg: float = Field(description="sway/pan amplitude or bump step [deg]")
    axis: Literal["pan", "tilt", "roll"] | None = Field(None, description="None = pan for 'pan', tilt otherwise")
    start_s: float = Field(0.0, ge=0.0, description="when the motion starts [s]")
    period_s: float = Field(4.0, gt=0.0, description="sway/pan period [s]")
    duration_s: float = Field(0.1, gt=0.0, description="bump rise time [s]")

    @property
    def rotation_axis(self) -> str:
        """The axis actually used (``axis`` or the kind's default)."""
        return self.axis or ("pan" if self.kind == "pan" else "tilt")

    def angle_rad(self, times_s) -> np.ndarray:
        """Rotation angle [rad] at each time (N,)."""
        t = np.asarray(times_s, dtype=float) - self.start_s
        a = np.radians(self.amplitude_deg)
        if self.kind == "bump":
            s = np.clip(t / self.duration_s, 0.0, 1.0)
            return a * 0.5 * (1.0 - np.cos(np.pi * s))
        return np.where(t >= 0, a * np.sin(2 * np.pi * t / self.period_s), 0.0)


def _axis_world(axis: str, R_world_cam0: np.ndarray) -> np.ndarray:
    if axis == "pan":
        return np.array([0.0, 0.0, 1.0])
    return R_world_cam0[:, 0] if axis == "tilt" else R_world_cam0[:, 2]


def R_world_cam_at(R_world_cam0, motions, times_s) -> np.ndarray:
    """Camera attitude at each time: ``(N, 3, 3)`` rotations camera -> world.

    Parameters
    ----------
    R_world_cam0 : array_like, shape (3, 3)
        Rest (calibrated) attitude.
    motions : sequence of CameraMotionSpec
        Applied in order (an empty sequence: the camera does not move).
    times_s : array_like, shape (N,)
    """
    R0 = np.asarray(R_world_cam0, dtype=float)
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    R = np.broadcast_to(R0, (len(t), 3, 3)).copy()
    for m in motions:
        rotvec = m.angle_rad(t)[:, None] * _axis_world(m.rotation_axis, R0)[None]
        R = Rotation.from_rotvec(rotvec).as_matrix() @ R
    return R


def omega_cam_rad_s_at(R_world_cam0, motions, times_s, step_s: float = 1e-4) -> np.ndarray:
    """Angular rate of the camera in its own frame [rad/s], (N, 3): ``vee(R^T dR/dt)``.

    Central difference over ``+-step_s`` of :func:`R_world_cam_at` (the motions are smooth except at a
    sway's or pan's start and at a bump's ends, where the rate jumps and the difference averages it).
    """
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    Ra = R_world_cam_at(R_world_cam0, motions, t - step_s)
    Rb = R_world_cam_at(R_world_cam0, motions, t + step_s)
    return Rotation.from_matrix(np.swapaxes(Ra, -1, -2) @ Rb).as_rotvec() / (2 * step_s)


def max_motion_deg(motions) -> float:
    """Upper bound of how far the camera turns from rest [deg] (sum of the amplitudes)."""
    return float(sum(abs(m.amplitude_deg) for m in motions))
