"""A one-scanner plane's tilt error from a known twist error against its widened covariance."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from planodom.config import ExtractionConfig
from planodom.errors import ConfigError
from planodom.extraction.deskew import deskew_points
from planodom.extraction.planes.fit import tls_covariance, tls_fit
from planodom.extraction.rig2d.onescanner import twist_covariance

#: The turn's true twist (13 deg/s, 5 m/s forward) and the rate error (1 deg/s of yaw).
_TWIST = np.array([0.0, 0.0, np.radians(13.0), 5.0, 0.0, 0.0])
_RATE_ERR = np.radians(1.0)


def _one_scanner_wall(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Raw points (M, 3) of a side wall ``y = 12`` 30-40 m ahead seen by one scanner as
    four parallel lines (slope 5 deg, 0.3 m apart across each other), one a 40 ms sweep,
    their times (M,) s and the true plane (4,) (normal towards the sensor)."""
    u = np.array([np.cos(np.radians(5.0)), 0.0, np.sin(np.radians(5.0))])  # along the lines
    w = np.array([-u[2], 0.0, u[0]])  # across them, in the wall
    pts, ts = [], []
    for s in range(4):
        lam = np.linspace(-5.0, 5.0, 200)
        p = np.array([35.0, 12.0, 1.0]) + 0.3 * s * w + lam[:, None] * u
        pts.append(p)
        ts.append(np.full(len(lam), 0.04 * s) + np.linspace(0.0, 0.01, len(lam)))
    p_ref, t = np.concatenate(pts), np.concatenate(ts)
    raw = deskew_points(p_ref, t, -_TWIST)  # seen at t: exp(-t xi) p_ref
    raw += rng.normal(scale=0.006, size=raw.shape)  # 6 mm of range noise
    return raw, t, np.array([0.0, -1.0, 0.0, 12.0])


def _nees(fitted: np.ndarray, truth: np.ndarray, cov: np.ndarray) -> float:
    """2-DoF NEES of a fit's normal (``fitted`` (n, d) (4,), its covariance (4, 4))
    against the truth, in the normal's tangent. The normal only: a tilt of degrees moves
    the offset at the origin by second-order terms of centimetres (``d (1 - cos)``, 4 cm
    here), which no first-order covariance holds."""
    n = fitted[:3]
    B = np.linalg.svd(np.eye(3) - np.outer(n, n))[0][:, :2]  # a tangent basis of n
    e = B.T @ (truth[:3] - n)
    C = B.T @ cov[:3, :3] @ B
    return float(e @ np.linalg.solve(C, e))


def test_tilt_error_of_a_wrong_rate_lies_within_the_widened_covariance() -> None:
    raw, t, truth = _one_scanner_wall(np.random.default_rng(3))
    wrong = _TWIST + np.array([0.0, 0.0, _RATE_ERR, 0.0, 0.0, 0.0])
    pts = deskew_points(raw, t, wrong)
    c, evals, evecs = tls_fit(pts)
    n = evecs[:, 2] * (1.0 if evecs[1, 2] < 0 else -1.0)  # towards the sensor, as the truth
    fitted = np.append(n, -n @ c)
    fit_cov = tls_covariance(evals[None], evecs[None], c[None], np.array([len(pts)]), 0.006)[0]
    tilt_deg = np.degrees(np.arccos(min(abs(n @ truth[:3]), 1.0)))
    assert tilt_deg > 2.0  # the rate error tilts the wall by degrees: the case at hand
    widened = fit_cov + twist_covariance(pts, t, n, _RATE_ERR, 0.05)
    gate = chi2.ppf(0.99, 2)
    assert _nees(fitted, truth, widened) < gate  # the widened covariance holds the error
    assert _nees(fitted, truth, fit_cov) > 100 * gate  # the fit's alone does not


def test_the_option_is_off_by_default_and_validated() -> None:
    cfg = ExtractionConfig()
    assert cfg.single_scanner_rate_sigma_deg_s == 0.0
    assert cfg.single_scanner_speed_sigma_mps == 0.0
    try:
        ExtractionConfig(single_scanner_rate_sigma_deg_s=-1.0)
    except (ConfigError, ValueError) as err:
        assert "single_scanner_rate_sigma_deg_s" in str(err)
    else:
        raise AssertionError("a negative sigma was accepted")
