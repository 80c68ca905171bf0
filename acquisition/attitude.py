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

Gimbal lock. A gimbal looking straight down has Euler pitch -90, where yaw and roll turn about
the same axis and only their sum is defined: :func:`euler_deg_from_quat` then gives roll 0 and
the whole turn as yaw (the heading of the image top), and vehicle and gimbal are combined and
interpolated as quaternions, never through Euler angles in between.
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


#: Below this cos(pitch) the Euler angles are in gimbal lock (pitch within 6e-7 deg of +-90):
#: yaw and roll then turn about the same axis, and only their sum (pitch -90) or difference
#: (pitch +90) is defined.
_LOCK_COS = 1e-8


def euler_deg_from_quat(q: ArrayLike) -> tuple[F64, F64, F64]:
    """(yaw 0-360, pitch -90..90, roll -180..180) degrees of quaternions (w, x, y, z).

    At pitch +-90 (gimbal lock, e.g. a gimbal looking straight down) the rotation is carried by
    the yaw alone and the roll is 0, so that yaw stays the heading of the body's y axis turned
    back by 90 degrees (for a nadir gimbal: where the top of the image points) instead of two
    ill-conditioned angles whose sum alone is defined."""
    qa = np.atleast_2d(np.asarray(q, float))
    qa = qa / np.linalg.norm(qa, axis=1, keepdims=True)
    w, x, y, z = qa[:, 0], qa[:, 1], qa[:, 2], qa[:, 3]
    # Elements of the rotation matrix ned_from_body.
    r00 = 1.0 - 2.0 * (y * y + z * z)
    r10 = 2.0 * (x * y + w * z)
    r20 = 2.0 * (x * z - w * y)
    r21 = 2.0 * (y * z + w * x)
    r22 = 1.0 - 2.0 * (x * x + y * y)
    r01 = 2.0 * (x * y - w * z)
    r11 = 1.0 - 2.0 * (x * x + z * z)
    cos_pitch = np.hypot(r00, r10)
    locked = cos_pitch < _LOCK_COS
    pitch = np.degrees(np.arctan2(-r20, cos_pitch))
    yaw = np.where(locked, np.arctan2(-r01, r11), np.arctan2(r10, r00))
    roll = np.where(locked, 0.0, np.arctan2(r21, r22))
    yaw_deg = np.degrees(yaw) % 360.0
    yaw_deg = np.where(yaw_deg >= 360.0, 0.0, yaw_deg)  # -1e-30 % 360 rounds to 360.0
    return (
        np.asarray(yaw_deg, float),
        np.asarray(pitch, float),
        np.asarray(np.degrees(roll), float),
    )


def roll_pitch_yaw_deg_from_quaternion(
    w: ArrayLike, x: ArrayLike, y: ArrayLike, z: ArrayLike
) -> tuple[F64, F64, F64]:
    """(roll, pitch, yaw) in degrees, Tait-Bryan z-y'-x'' (yaw, then pitch, then roll), of the
    rotation from body (FRD) to local NED given as quaternion components (w, x, y, z) of any
    equal shapes, the convention of MAVLink and PX4. Yaw is 0-360 clockwise from north; the
    quaternion need not be unit (a zero quaternion reads as no rotation). At pitch +-90 (a gimbal
    looking straight down) the roll is 0 and the yaw carries the whole turn
    (:func:`euler_deg_from_quat`)."""
    q = np.stack([np.asarray(a, dtype=np.float64) for a in np.broadcast_arrays(w, x, y, z)], axis=-1)
    flat = np.atleast_2d(q.reshape(-1, 4)).copy()
    zero = np.linalg.norm(flat, axis=1) == 0
    flat[zero] = (1.0, 0.0, 0.0, 0.0)
    yaw, pitch, roll = euler_deg_from_quat(flat)
    shape = q.shape[:-1]
    return roll.reshape(shape)[()], pitch.reshape(shape)[()], yaw.reshape(shape)[()]


def quat_from_yaw_deg(yaw_deg: ArrayLike) -> F64:
    """Rotations about the down axis by ``yaw_deg`` (clockwise seen from above), (N, 4)."""
    half = np.radians(np.asarray(yaw_deg, float)) / 2.0
    zero = np.zeros_like(half)
    return np.asarray(np.atleast_2d(np.stack([np.cos(half), zero, zero, np.sin(half)], axis=-1)), float)


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


class CameraMount(StrEnum):
    """How the camera is carried, which decides the camera's attitude when the log has no gimbal
    angles (a log that has them gives the camera's own, whatever this says).

    - ``gimbal``: on a stabilised gimbal looking straight down, as every sfap plan points it (the
      mission's first item): the vehicle's pitch and roll are the gimbal's to cancel, not the
      camera's; the camera's heading is the vehicle's.
    - ``fixed``: fixed to the airframe looking down (a fixed wing's hatch, no gimbal): the
      vehicle's attitude is the camera's.
    - ``auto``: as the log says the vehicle is: a fixed wing or a VTOL (a fixed wing with lift
      rotors, which flies its survey lines as one and carries its camera in the fuselage, as
      Wingtra's, DeltaQuad's and Quantum's do) ``fixed``; a multirotor, a helicopter, another
      vehicle or a log that does not say ``gimbal``.
    """

    GIMBAL = "gimbal"
    FIXED = "fixed"
    AUTO = "auto"


def heading_only_deg(yaw_deg: ArrayLike) -> tuple[F64, F64, F64]:
    """(yaw, pitch, roll) of a nadir camera on a stabilised gimbal that follows the vehicle's
    heading: the heading, and no pitch or roll (the convention of the module docstring)."""
    yaw = np.asarray(yaw_deg, float)
    return yaw, np.zeros_like(yaw), np.zeros_like(yaw)


# ned_from_camera of a gimbal times this = a virtual airframe whose down axis is the boresight.
_NADIR_FROM_FORWARD = quat_from_euler_deg(0.0, 90.0, 0.0)


def camera_quat(
    vehicle_q: ArrayLike, gimbal_q: ArrayLike | None = None, mode: GimbalMode = GimbalMode.EARTH
) -> F64:
    """ned_from_camera quaternions (N, 4) of the virtual airframe of the module docstring: its
    down axis is the camera's optical axis and its nose the top of the image.

    ``vehicle_q``: ned_from_body of the vehicle. ``gimbal_q``: the gimbal's rotation of a
    forward-looking camera (x the optical axis, y image right, z image down), referenced as
    ``mode`` says: from NED (earth), from NED turned by the vehicle's yaw (stabilized), or from
    the body (body). Without a gimbal the camera is fixed to the airframe, looking down.
    """
    vq = np.atleast_2d(np.asarray(vehicle_q, float))
    if gimbal_q is None:
        return vq
    gq = np.atleast_2d(np.asarray(gimbal_q, float))
    if mode is GimbalMode.EARTH:
        ned_from_camera = gq
    elif mode is GimbalMode.STABILIZED:
        vehicle_yaw, _, _ = euler_deg_from_quat(vq)
        ned_from_camera = quat_multiply(quat_from_yaw_deg(vehicle_yaw), gq)
    else:
        ned_from_camera = quat_multiply(vq, gq)
    return quat_multiply(ned_from_camera, np.broadcast_to(_NADIR_FROM_FORWARD, ned_from_camera.shape))


def camera_attitude_deg(
    vehicle_ypr_deg: tuple[ArrayLike, ArrayLike, ArrayLike],
    gimbal_ypr_deg: tuple[ArrayLike, ArrayLike, ArrayLike] | None = None,
    mode: GimbalMode = GimbalMode.EARTH,
) -> tuple[F64, F64, F64]:
    """Camera (yaw, pitch, roll) in the convention of the module docstring, from the vehicle's
    and the gimbal's Euler angles (see :func:`camera_quat`).

    Without gimbal angles the camera is taken as fixed to the airframe, looking down.
    """
    vehicle_q = quat_from_euler_deg(*vehicle_ypr_deg)
    gimbal_q = None if gimbal_ypr_deg is None else quat_from_euler_deg(*gimbal_ypr_deg)
    return euler_deg_from_quat(camera_quat(vehicle_q, gimbal_q, mode))
