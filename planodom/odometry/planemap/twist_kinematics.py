"""What a scan's registered pose says about its twist: the step from the previous pose.

Two registered poses ``span`` s apart (world from scan, at their reference times) give
the step's mean twist ``z = log(T_prev^-1 T) / span`` (6,) rad/s, m/s: under a constant
rate that is ``xi - a span / 2`` of the state ``(xi, a)`` at the later scan (the twist
half a step back, what the constant-velocity twist is), to within the poses' errors
(over ``span``) and the rate's random walk over the step (``q span^3 / 20`` per axis).
Precise, but late; the scan's own registered twist (:mod:`.ctreg`) is current, but
noisier: the filter (:mod:`.twist_filter`) fuses both.
"""

from __future__ import annotations

import numpy as np

from planodom.geometry import se3_log


def step_measurement(
    T_prev: np.ndarray, cov_prev: np.ndarray, T: np.ndarray, cov: np.ndarray, span: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The step's mean twist ``z`` (6,), its matrix ``Hs`` (6, 12) on the state (``z = Hs
    s``) and its covariance (6, 6) from the poses' (world-frame perturbations (6, 6) of
    ``T_prev`` and ``T`` (4, 4), summed and turned into the earlier scan's frame),
    without the random walk's."""
    z = se3_log(np.linalg.inv(T_prev) @ T) / span
    Hs = np.hstack([np.eye(6), -0.5 * span * np.eye(6)])
    Rb = np.zeros((6, 6))
    Rb[:3, :3] = Rb[3:, 3:] = T_prev[:3, :3].T
    return z, Hs, Rb @ (cov_prev + cov) @ Rb.T / span**2


def step_q_sample(
    z: np.ndarray, Hs: np.ndarray, mean: np.ndarray, cov: np.ndarray, Rz: np.ndarray, span: float
) -> np.ndarray:
    """(6,) one covariance-matching sample of the jerk density (rotation's three axes
    alike, translation's alike): the step's squared innovation against the state
    predicted without process noise (``mean`` (12,), ``cov`` (12, 12)) less
    what its covariance and the poses' ``Rz`` explain (at least zero: the start's wide
    covariance would otherwise hold the mean below zero for the whole run), over the
    walk's ``3 span^3 / 20``."""
    nu = z - Hs @ mean
    var = np.diag(Hs @ cov @ Hs.T) + np.diag(Rz)
    rot = max(nu[:3] @ nu[:3] - var[:3].sum(), 0.0) / (3.0 * span**3 / 20.0)
    tra = max(nu[3:] @ nu[3:] - var[3:].sum(), 0.0) / (3.0 * span**3 / 20.0)
    return np.r_[np.full(3, rot), np.full(3, tra)]
