"""The SE(3) exponential and logarithm of twists (rad, m), batched and compiled
(split from :mod:`planodom.geometry`, which re-exports them)."""

from __future__ import annotations

import functools

import numba
import numpy as np

from planodom.fma import fma as _fma
from planodom.rotvec import _rotvec_kernel, rotation_vectors


def _skew(w: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrices (N, 3, 3) of vectors ``w`` (N, 3): ``skew(w) @ v = w x v``."""
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    return K - np.swapaxes(K, 1, 2)


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """SE(3) exponential of twists ``xi`` (..., 6) = (wx, wy, wz, vx, vy, vz), rad and m.

    Returns ``T = exp(xi)`` (..., 4, 4): (4, 4) for one twist. Our own closed form,
    batched (gtsam's ``Pose3.Expmap`` takes one twist per call); below 1e-3 rad the closed
    forms cancel catastrophically and the Taylor series to th^4 (exact to ~1e-19) is used.
    """
    xi = np.asarray(xi, dtype=np.float64)
    flat = xi.reshape(-1, 6)
    contiguous = np.ascontiguousarray(flat)
    if not contiguous.flags.writeable:  # one compiled layout (a read-only one compiles again)
        contiguous = contiguous.copy()
    out, code = _se3_exp_kernel(contiguous, _NO_CUBE)  # compiled, the same bits
    if code == _NEEDS_CUBE:  # an angle on the closed form: its th**3 is numpy's power
        out, code = _se3_exp_kernel(contiguous, np.linalg.norm(flat[:, :3], axis=1) ** 3)
    if code == _DONE:
        return out.reshape(xi.shape[:-1] + (4, 4))
    w, v = flat[:, :3], flat[:, 3:]
    th = np.linalg.norm(w, axis=1)
    small = th < 1e-3
    if len(flat) == 1:  # one twist (a prediction an epoch): its own branch only, the same ops
        a, b, c = _series(th) if small[0] else _closed(th)
    else:
        pairs = zip(_series(th), _closed(np.where(small, 1.0, th)), strict=True)
        a, b, c = (np.where(small, p, q) for p, q in pairs)
    K = _skew(w)
    K2 = K @ K
    eye = np.eye(3)
    out = np.zeros((len(flat), 4, 4))
    out[:, :3, :3] = eye + a[:, None, None] * K + b[:, None, None] * K2
    V = eye + b[:, None, None] * K + c[:, None, None] * K2
    out[:, :3, 3] = np.einsum("tij,tj->ti", V, v)
    out[:, 3, 3] = 1.0
    return out.reshape(xi.shape[:-1] + (4, 4))


#: :func:`_se3_exp_kernel`'s codes: its output is the twists' exponentials; an angle is on
#: the closed form and ``cube`` was not given; a non-finite angle (left to numpy).
_DONE, _NEEDS_CUBE, _NOT_FINITE = 0, 1, 2
_NO_CUBE = np.empty(0)


@numba.njit(cache=True)
def _se3_exp_kernel(flat, cube):  # pragma: no cover - compiled
    """:func:`se3_exp` of twists (N, 6), the same operations in the same order as its numpy
    form (so the same bits: the norm summed as numpy's reduction adds three terms, ``sin``
    and ``cos`` libm's as numpy's are, ``K @ K`` as OpenBLAS forms it, each product added
    by a fused multiply-add in order, the ``einsum`` as numpy adds its three terms on
    x86-64, the first and the last, then the middle, added to its zeroed output: an
    all-zero sum is +0), and a code (:data:`_DONE`, else the output is not used). The
    closed form's ``th**3`` is numpy's own ``power`` (not libm's ``pow``: they differ in
    the last bit on 5 % of angles): ``cube`` (N,) gives it, computed by numpy, or is empty
    (then :data:`_NEEDS_CUBE` when an angle is 1e-3 rad or more). Its ~25 numpy calls cost
    ~40 us on the one twist a Gauss-Newton step or a prediction asks for."""
    n = flat.shape[0]
    out = np.zeros((n, 4, 4))
    K = np.zeros((3, 3))
    K2 = np.empty((3, 3))
    V = np.empty((3, 3))
    for r in range(n):
        w0, w1, w2 = flat[r, 0], flat[r, 1], flat[r, 2]
        th = np.sqrt((w0 * w0 + w1 * w1) + w2 * w2)
        if not np.isfinite(th):
            return out, _NOT_FINITE
        if th < 1e-3:
            t2 = th * th
            a = (1.0 - t2 / 6.0) + (t2 * t2) / 120.0
            b = (0.5 - t2 / 24.0) + (t2 * t2) / 720.0
            c = (1.0 / 6.0 - t2 / 120.0) + (t2 * t2) / 5040.0
        elif cube.shape[0] == 0:
            return out, _NEEDS_CUBE
        else:
            s = np.sin(th)
            a = s / th
            b = (1.0 - np.cos(th)) / (th * th)
            c = (th - s) / cube[r]
        # _skew: the upper entries set, then K - K^T (its zeros' signs as numpy's)
        u01, u02, u12 = -w2, w1, -w0
        K[0, 0], K[0, 1], K[0, 2] = 0.0 - 0.0, u01 - 0.0, u02 - 0.0
        K[1, 0], K[1, 1], K[1, 2] = 0.0 - u01, 0.0 - 0.0, u12 - 0.0
        K[2, 0], K[2, 1], K[2, 2] = 0.0 - u02, 0.0 - u12, 0.0 - 0.0
        for i in range(3):
            for j in range(3):
                K2[i, j] = _fma(K[i, 2], K[2, j], _fma(K[i, 1], K[1, j], K[i, 0] * K[0, j]))
        for i in range(3):
            for j in range(3):
                e = 1.0 if i == j else 0.0
                out[r, i, j] = (e + a * K[i, j]) + b * K2[i, j]
                V[i, j] = (e + b * K[i, j]) + c * K2[i, j]
        v0, v1, v2 = flat[r, 3], flat[r, 4], flat[r, 5]
        for i in range(3):
            out[r, i, 3] = 0.0 + ((V[i, 0] * v0 + V[i, 2] * v2) + V[i, 1] * v1)  # from +0
        out[r, 3, 3] = 1.0
    return out, _DONE


def _series(th: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`se3_exp`'s coefficients ``sin(th) / th``, ``(1 - cos th) / th^2`` and
    ``(th - sin th) / th^3`` of angles ``th`` (N,), rad, by their Taylor series to th^4."""
    t2 = th**2
    return (
        1.0 - t2 / 6.0 + t2**2 / 120.0,
        0.5 - t2 / 24.0 + t2**2 / 720.0,
        1.0 / 6.0 - t2 / 120.0 + t2**2 / 5040.0,
    )


def _closed(th: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_series`'s coefficients in closed form (``th`` not zero)."""
    return np.sin(th) / th, (1.0 - np.cos(th)) / th**2, (th - np.sin(th)) / th**3


def twist_step(twist: np.ndarray, dt: float) -> np.ndarray:
    """(4, 4) ``se3_exp(twist * dt)`` of a twist (6,) (rad/s, m/s) over ``dt`` seconds,
    remembered for the last few (twist, dt) (by the twist's bytes: the same bits): the
    streaming odometry asks for its constant-velocity prediction with every extraction
    of an epoch. Read-only: shared."""
    return _twist_step(np.asarray(twist, dtype=np.float64).tobytes(), float(dt))


@functools.lru_cache(maxsize=4)
def _twist_step(twist: bytes, dt: float) -> np.ndarray:
    step = se3_exp(np.frombuffer(twist, dtype=np.float64) * dt)
    step.flags.writeable = False
    return step


def se3_log(T: np.ndarray) -> np.ndarray:
    """Twists ``(w, v)`` (..., 6) with ``exp(xi) = T`` for rigid transforms ``T`` (..., 4, 4).

    ``w`` is the rotation vector of ``R``; ``v = J_l(w)^-1 t`` with the closed-form inverse
    left Jacobian ``I - [w]x / 2 + (1 / a^2 - (1 + cos a) / (2 a sin a)) [w]x^2`` (series
    below 1e-6 rad). A constant-velocity twist over ``dt`` seconds is ``se3_log(T_a_b) / dt``.
    """
    T = np.asarray(T, dtype=np.float64)
    flat = np.ascontiguousarray(T.reshape(-1, 4, 4))
    out, ok = _se3_log_kernel(flat)
    if not ok.all():  # rotations scipy orthogonalises first (or refuses): as it does
        out[~ok] = _se3_log_rows(flat[~ok])
    return out.reshape(T.shape[:-2] + (6,))


@numba.njit(cache=True)
def _se3_log_kernel(flat):  # pragma: no cover - compiled
    """:func:`_se3_log_rows` of (N, 4, 4) transforms in one compiled pass, the same
    operations in the same order (so the same bits; the numpy form's ~20 calls cost ~40 us
    on the one transform an epoch estimate asks for), and (N,) whether each rotation was
    orthonormal enough to be taken as it is (:mod:`planodom.rotvec`; else left to it)."""
    w, ok = _rotvec_kernel(flat[:, :3, :3].copy())
    out = np.zeros((flat.shape[0], 6))
    for k in range(flat.shape[0]):
        w0, w1, w2 = w[k, 0], w[k, 1], w[k, 2]
        t0, t1, t2 = flat[k, 0, 3], flat[k, 1, 3], flat[k, 2, 3]
        a = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        if a < 1e-6:
            c = 1.0 / 12.0 + a * a / 720.0
        else:
            c = 1.0 / (a * a) - (1.0 + np.cos(a)) / (2.0 * a * np.sin(a))
        x0, x1, x2 = w1 * t2 - w2 * t1, w2 * t0 - w0 * t2, w0 * t1 - w1 * t0  # w x t
        y0, y1, y2 = w1 * x2 - w2 * x1, w2 * x0 - w0 * x2, w0 * x1 - w1 * x0  # w x (w x t)
        out[k, 0], out[k, 1], out[k, 2] = w0, w1, w2
        out[k, 3] = t0 - 0.5 * x0 + c * y0
        out[k, 4] = t1 - 0.5 * x1 + c * y1
        out[k, 5] = t2 - 0.5 * x2 + c * y2
    return out, ok


def _se3_log_rows(flat: np.ndarray) -> np.ndarray:
    """:func:`se3_log` of (N, 4, 4) transforms, in numpy (rotation vectors as scipy's)."""
    w = rotation_vectors(flat[:, :3, :3])  # scipy's as_rotvec, compiled
    t = flat[:, :3, 3]
    a = np.linalg.norm(w, axis=1)
    small = a < 1e-6
    safe = np.where(small, 1.0, a)
    c = np.where(
        small,
        1.0 / 12.0 + a * a / 720.0,
        1.0 / safe**2 - (1.0 + np.cos(safe)) / (2.0 * safe * np.sin(safe)),
    )
    wxt = cross_rows(w, t)
    v = t - 0.5 * wxt + c[:, None] * cross_rows(w, wxt)
    return np.concatenate([w, v], axis=1)


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of (M, 3) arrays: ``np.cross`` without its axis handling,
    which costs more than the products for the few rows of a plane set."""
    same = a.shape == b.shape  # the common case: skip broadcast_shapes' cost
    out = np.empty(a.shape if same else np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out
