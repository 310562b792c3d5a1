"""Rotation helpers, batched. Quaternions are ``quat_xyzw`` (PyBullet order)."""

from __future__ import annotations

import numpy as np

__all__ = [
    "cross_rows",
    "hat",
    "quat_xyzw_from_rotation",
    "quat_xyzw_from_yaw",
    "rotation_from_quat_xyzw",
    "rotation_from_thrust_axis_and_yaw",
    "vee",
    "yaw_from_rotation",
]


def rotation_from_quat_xyzw(quat_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrices from unit quaternions.

    Args:
        quat_xyzw: (..., 4) quaternions, x, y, z, w order.

    Returns:
        (..., 3, 3) rotation matrices (body -> world for a body attitude).
    """
    q = np.asarray(quat_xyzw, float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - z * w)
    R[..., 0, 2] = 2 * (x * z + y * w)
    R[..., 1, 0] = 2 * (x * y + z * w)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - x * w)
    R[..., 2, 0] = 2 * (x * z - y * w)
    R[..., 2, 1] = 2 * (y * z + x * w)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def quat_xyzw_from_rotation(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) xyzw (w >= 0) from rotation matrices (..., 3, 3)."""
    R = np.asarray(R, float)
    shape = R.shape[:-2]
    R = R.reshape(-1, 3, 3)
    q = np.empty((R.shape[0], 4))
    tr = np.trace(R, axis1=1, axis2=2)
    for i in range(R.shape[0]):  # branch per matrix (Shepperd's method); small counts only
        m = R[i]
        if tr[i] > 0:
            s = 2.0 * np.sqrt(tr[i] + 1.0)
            q[i] = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
        elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
            s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
            q[i] = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
        elif m[1, 1] > m[2, 2]:
            s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
            q[i] = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
        else:
            s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
            q[i] = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    q *= np.where(q[:, 3:4] < 0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.reshape(shape + (4,))


def quat_xyzw_from_yaw(yaw: float) -> np.ndarray:
    """Quaternion (4,) xyzw of a pure rotation by ``yaw`` [rad] about world z."""
    return np.array([0.0, 0.0, np.sin(yaw / 2.0), np.cos(yaw / 2.0)])


def yaw_from_rotation(R: np.ndarray) -> np.ndarray:
    """Heading [rad] of the body x axis about world z, from (..., 3, 3) -> (...)."""
    return np.arctan2(R[..., 1, 0], R[..., 0, 0])


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of (..., 3) arrays along the last axis (np.cross costs several times more at small N)."""
    return np.stack(
        [a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1], a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2], a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]],
        axis=-1,
    )


def rotation_from_thrust_axis_and_yaw(b3_world: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Body-to-world rotations (..., 3, 3) with body z along ``b3_world`` and heading ``yaw``.

    The construction of Lee et al. (2010) and Mellinger & Kumar (2011):
    ``b1_c = (cos yaw, sin yaw, 0)``, ``b2 = b3 x b1_c / |b3 x b1_c|``,
    ``b1 = b2 x b3``.

    Args:
        b3_world: (..., 3) unit thrust axes in world.
        yaw: (...) headings [rad].
    """
    b1_c = np.stack([np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)], axis=-1)
    b2 = cross_rows(b3_world, b1_c)
    b2 /= np.linalg.norm(b2, axis=-1, keepdims=True)
    b1 = cross_rows(b2, b3_world)
    return np.stack([b1, b2, b3_world], axis=-1)


def hat(v: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrices (..., 3, 3) with hat(a) b = a x b, from (..., 3)."""
    v = np.asarray(v, float)
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def vee(S: np.ndarray) -> np.ndarray:
    """Inverse of :func:`hat`: (..., 3, 3) skew matrices -> (..., 3)."""
    return np.stack([S[..., 2, 1], S[..., 0, 2], S[..., 1, 0]], axis=-1)
