"""Rotation vectors of rotation matrices and back, compiled (numba).

:func:`rotation_vectors` gives the bits of scipy's
``Rotation.from_matrix(R).as_rotvec()`` (1.17: Markley's choice of the largest of the
diagonal and the trace, a normalised canonical quaternion, ``angle / sin(angle / 2)``
with its series below 1e-3 rad), written out per matrix: scipy's per-call overhead
(~50 us) was a fifth of a relative-pose solve's rotation log
(:func:`planodom.geometry.se3_log`, once per epoch estimate). Matrices scipy would first
orthogonalise (not orthogonal to 1e-12) or refuse (determinant <= 0) go to scipy itself.

:func:`rotation_matrices` gives the bits of ``Rotation.from_rotvec(w).as_matrix()``
(1.17: the quaternion ``(sin(a / 2) / a w, cos(a / 2))``, its series below 1e-3 rad, not
normalised, and its matrix), for the Gauss-Newton steps of the map registration (one a
step, ~30 us of scipy's overhead each).
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.spatial.transform import Rotation


def rotation_vectors(R: np.ndarray) -> np.ndarray:
    """(N, 3) rotation vectors (rad) of rotation matrices ``R`` (N, 3, 3)."""
    R = np.ascontiguousarray(R, dtype=np.float64)
    out, ok = _rotvec_kernel(R)
    if not ok.all():
        out[~ok] = Rotation.from_matrix(R[~ok]).as_rotvec()
    return out


@numba.njit(cache=True)
def _orthonormal(m):  # pragma: no cover - compiled
    """Whether scipy takes the (3, 3) ``m`` as a rotation without orthogonalising it:
    determinant > 0 and ``m m^T`` within ``isclose(atol=1e-12)`` (rtol 1e-5) of I."""
    det = (
        m[0, 0] * (m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1])
        - m[0, 1] * (m[1, 0] * m[2, 2] - m[1, 2] * m[2, 0])
        + m[0, 2] * (m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0])
    )
    if not det > 0:
        return False
    for i in range(3):
        for j in range(3):
            g = m[i, 0] * m[j, 0] + m[i, 1] * m[j, 1] + m[i, 2] * m[j, 2]
            e = 1.0 if i == j else 0.0
            if not abs(g - e) <= 1e-12 + 1e-5 * abs(e):
                return False
    return True


@numba.njit(cache=True)
def _rotvec_kernel(R):  # pragma: no cover - compiled
    """(N, 3) rotation vectors and (N,) bool: computed here (False: left to scipy)."""
    n = R.shape[0]
    out = np.zeros((n, 3))
    ok = np.ones(n, dtype=np.bool_)
    q = np.empty(4)
    for k in range(n):
        m = R[k]
        if not _orthonormal(m):
            ok[k] = False
            continue
        tr = m[0, 0] + m[1, 1] + m[2, 2]
        choice, best = 0, m[0, 0]
        if m[1, 1] > best:
            choice, best = 1, m[1, 1]
        if m[2, 2] > best:
            choice, best = 2, m[2, 2]
        if tr > best:
            choice = 3
        if choice == 3:
            q[0], q[1], q[2] = m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]
            q[3] = 1.0 + tr
        else:
            i = choice
            j, h = (i + 1) % 3, (i + 2) % 3
            q[i] = 1.0 - tr + 2.0 * m[i, i]
            q[j] = m[j, i] + m[i, j]
            q[h] = m[h, i] + m[i, h]
            q[3] = m[h, j] - m[j, h]
        nq = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        for u in range(4):
            q[u] = q[u] / nq
        x, y, z = q[0] == 0, q[1] == 0, q[2] < 0
        if q[3] < 0 or (q[3] == 0 and (q[0] < 0 or (x and (q[1] < 0 or (y and z))))):
            for u in range(4):
                q[u] = -q[u]
        angle = 2.0 * np.arctan2(np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]), q[3])
        if angle <= 1e-3:
            a2 = angle * angle
            scale = 2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0
        else:
            scale = angle / np.sin(angle / 2.0)
        out[k, 0], out[k, 1], out[k, 2] = scale * q[0], scale * q[1], scale * q[2]
    return out, ok


def rotation_matrices(rotvecs: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices of the rotation vectors ``rotvecs`` (N, 3), rad; (3, 3)
    for one vector (3,): scipy's ``Rotation.from_rotvec(rotvecs).as_matrix()``, bit for
    bit."""
    w = np.ascontiguousarray(rotvecs, dtype=np.float64)
    out = _matrices_kernel(w.reshape(-1, 3))
    return out[0] if w.shape == (3,) else out


@numba.njit(cache=True)
def _matrices_kernel(w):  # pragma: no cover - compiled
    """(N, 3, 3) matrices of the rotation vectors ``w`` (N, 3), with scipy's arithmetic."""
    n = w.shape[0]
    out = np.empty((n, 3, 3))
    for k in range(n):
        angle = np.sqrt(w[k, 0] * w[k, 0] + w[k, 1] * w[k, 1] + w[k, 2] * w[k, 2])
        if angle <= 1e-3:
            a2 = angle * angle
            scale = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
        else:
            scale = np.sin(angle / 2.0) / angle
        x, y, z = scale * w[k, 0], scale * w[k, 1], scale * w[k, 2]
        q = np.cos(angle / 2.0)
        x2, y2, z2, q2 = x * x, y * y, z * z, q * q
        xy, zq, xz, yq, yz, xq = x * y, z * q, x * z, y * q, y * z, x * q
        out[k, 0, 0] = x2 - y2 - z2 + q2
        out[k, 1, 0] = 2.0 * (xy + zq)
        out[k, 2, 0] = 2.0 * (xz - yq)
        out[k, 0, 1] = 2.0 * (xy - zq)
        out[k, 1, 1] = -x2 + y2 - z2 + q2
        out[k, 2, 1] = 2.0 * (yz + xq)
        out[k, 0, 2] = 2.0 * (xz + yq)
        out[k, 1, 2] = 2.0 * (yz - xq)
        out[k, 2, 2] = -x2 - y2 + z2 + q2
    return out
