"""Attitude math: quaternions, spherical interpolation, Euler angles and the camera attitude.

Quaternions are (w, x, y, z) rows of (N, 4) float arrays, the rotation ned_from_body; Euler
angles are aerospace Z-Y-X (yaw about down, then pitch, then roll), in degrees. Written here
because scipy is not a dependency. :func:`camera_attitude_deg` combines the vehicle's attitude
with a gimbal's (:class:`GimbalMode` says how the gimbal angles are referenced).

Camera attitude convention (written as Pix4D ``Camera:Yaw/Pitch/Roll``): the yaw, pitch and roll
of a virtual airframe whose downward-looking camera would point like the real one. A camera fixed
to the airframe looking down therefore carries the vehicle's own yaw (clockwise from north,
0-360), pitch (nose up positive) and roll (right wing down positive); a level, nadir camera has
pitch 0, roll 0.
"""

from __future__ import annotations

from enum import StrEnum

import numpy as np
from numpy.typing import ArrayLike, NDArray

F64 = NDArray[np.float64]


def quat_from_euler_deg(yaw_deg: ArrayLike, pitch_deg: ArrayLike, roll_deg: ArrayLike) -> F64:
    """Unit quaternions (w, x, y, z), shape (N, 4), of the rotation ned_from_body for
    aerospace Z-Y-X angles (yaw about down, then pitch, then roll)."""
    y = np.radians(np.asarray(yaw_deg, float)) / 2.0
    p = np.radians(np.asarray(pitch_deg, float)) / 2.0
    r = np.radians(np.asarray(roll_deg, float)) / 2.0
    cy, sy, cp, sp, cr, sr = np.cos(y), np.sin(y), np.cos(p), np.sin(p), np.cos(r), np.sin(r)
    q = np.stack(
        [
            cy * cp * cr + sy * sp * sr,
            cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr,
        ],
        axis=-1,
    )
    return np.asarray(np.atleast_2d(q), float)


def euler_deg_from_quat(q: ArrayLike) -> tuple[F64, F64, F64]:
    """(yaw 0-360, pitch -90..90, roll -180..180) degrees of quaternions (w, x, y, z)."""
    qa = np.atleast_2d(np.asarray(q, float))
    qa = qa / np.linalg.norm(qa, axis=1, keepdims=True)
    w, x, y, z = qa[:, 0], qa[:, 1], qa[:, 2], qa[:, 3]
    yaw = np.degrees(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))) % 360.0
    pitch = np.degrees(np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0)))
    roll = np.degrees(np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y)))
    return np.asarray(yaw, float), np.asarray(pitch, float), np.asarray(roll, float)


def quat_multiply(a: ArrayLike, b: ArrayLike) -> F64:
    """Hamilton product a * b of (N, 4) quaternion arrays (rotation b first, then a)."""
    qa = np.atleast_2d(np.asarray(a, float))
    qb = np.atleast_2d(np.asarray(b, float))
    w1, x1, y1, z1 = qa[:, 0], qa[:, 1], qa[:, 2], qa[:, 3]
    w2, x2, y2, z2 = qb[:, 0], qb[:, 1], qb[:, 2], qb[:, 3]
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def slerp(q0: ArrayLike, q1: ArrayLike, fraction: ArrayLike) -> F64:
    """Spherical linear interpolation between unit quaternions, row by row, shortest arc."""
    a = np.atleast_2d(np.asarray(q0, float))
    b = np.atleast_2d(np.asarray(q1, float)).copy()
    t = np.asarray(fraction, float).reshape(-1, 1)
    dot = np.sum(a * b, axis=1, keepdims=True)
    b = np.where(dot < 0.0, -b, b)  # q and -q are the same rotation: take the short way
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    near = sin_theta < 1e-9
    safe = np.where(near, 1.0, sin_theta)
    w0 = np.where(near, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(near, t, np.sin(t * theta) / safe)
    out = w0 * a + w1 * b
    return np.asarray(out / np.linalg.norm(out, axis=1, keepdims=True), float)


class GimbalMode(StrEnum):
    """How the log's gimbal angles relate to the world and the vehicle. In every mode the angles
    are those of the camera's optical axis (forward looking at pitch 0; -90 pitch looks down).

    - ``earth``: yaw clockwise from north, pitch and roll relative to the horizon: what the
      telemetry readers produce (they turn a vehicle-relative gimbal yaw into an earth yaw).
    - ``stabilized``: pitch and roll relative to the horizon, yaw relative to the vehicle's nose
      (ArduPilot MOUNT_STATUS as sent, most 3-axis gimbals).
    - ``body``: all three angles relative to the airframe (a gimbal that only rotates the camera
      on the body).
    """

    EARTH = "earth"
    STABILIZED = "stabilized"
    BODY = "body"


# ned_from_camera of a gimbal times this = a virtual airframe whose down axis is the boresight.
_NADIR_FROM_FORWARD = quat_from_euler_deg(0.0, 90.0, 0.0)


def camera_attitude_deg(
    vehicle_ypr_deg: tuple[ArrayLike, ArrayLike, ArrayLike],
    gimbal_ypr_deg: tuple[ArrayLike, ArrayLike, ArrayLike] | None = None,
    mode: GimbalMode = GimbalMode.EARTH,
) -> tuple[F64, F64, F64]:
    """Camera (yaw, pitch, roll) in the convention of the module docstring.

    Without gimbal angles the camera is taken as fixed to the airframe, looking down.
    """
    vehicle_q = quat_from_euler_deg(*vehicle_ypr_deg)
    if gimbal_ypr_deg is None:
        return euler_deg_from_quat(vehicle_q)
    g_yaw, g_pitch, g_roll = (np.asarray(a, float) for a in gimbal_ypr_deg)
    if mode is GimbalMode.EARTH:
        ned_from_camera = quat_from_euler_deg(g_yaw, g_pitch, g_roll)
    elif mode is GimbalMode.STABILIZED:
        v_yaw = np.asarray(vehicle_ypr_deg[0], float)
        ned_from_camera = quat_from_euler_deg(v_yaw + g_yaw, g_pitch, g_roll)
    else:
        ned_from_camera = quat_multiply(vehicle_q, quat_from_euler_deg(g_yaw, g_pitch, g_roll))
    return euler_deg_from_quat(quat_multiply(ned_from_camera, _NADIR_FROM_FORWARD))
