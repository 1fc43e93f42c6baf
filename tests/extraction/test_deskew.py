"""Deskewing: the compiled per-point SE(3) exponential, and plane fits on a moving rig."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from planodom.extraction import deskew_points, extract
from planodom.geometry import se3_exp

from .synth_scans import default_scene, planes_in_base, scan_rig

XI = np.array([0.05, -0.04, 0.6, 3.0, 0.4, 0.1])  # rad/s, m/s: a brisk turn


def hat(xi: np.ndarray) -> np.ndarray:
    w, v = xi[:3], xi[3:]
    M = np.zeros((4, 4))
    M[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
    M[:3, 3] = v
    return M


@pytest.mark.parametrize("scale", [1.0, 1e-6, 0.0])
def test_deskew_points_match_se3_exp(scale):
    # The compiled per-point kernel against the batched closed form and scipy's expm.
    rng = np.random.default_rng(3)
    p = rng.uniform(-60, 60, (500, 3))
    t = rng.uniform(-0.1, 0.2, 500)
    T = se3_exp(t[:, None] * (XI * scale))
    expected = np.einsum("nij,nj->ni", T[:, :3, :3], p) + T[:, :3, 3]
    np.testing.assert_allclose(deskew_points(p, t, XI * scale), expected, atol=1e-12)
    for k in range(0, 500, 50):
        Tk = expm(hat(XI * scale * t[k]))
        np.testing.assert_allclose(
            deskew_points(p[k : k + 1], t[k : k + 1], XI * scale)[0],
            Tk[:3, :3] @ p[k] + Tk[:3, 3],
            atol=1e-12,
        )


def test_points_with_the_same_time_are_deskewed_as_alone():
    """Runs of equal times (scanners that fire together) reuse one time's coefficients:
    every point must come out exactly as deskewed on its own, and as the closed form."""
    rng = np.random.default_rng(4)
    t = np.repeat(rng.uniform(-0.1, 0.2, 60), 4)
    t[:4] = 0.0
    t[8:12] = -0.0
    p = rng.uniform(-60, 60, (len(t), 3))
    out = deskew_points(p, t, XI)
    alone = np.vstack([deskew_points(p[i : i + 1], t[i : i + 1], XI) for i in range(len(t))])
    np.testing.assert_array_equal(out, alone)
    T = se3_exp(t[:, None] * XI)
    expected = np.einsum("nij,nj->ni", T[:, :3, :3], p) + T[:, :3, 3]
    np.testing.assert_allclose(out, expected, atol=1e-12)


def test_deskew_points_maps_to_reference_time():
    rng = np.random.default_rng(0)
    p_ref = rng.uniform(-10, 10, (50, 3))
    t = rng.uniform(0, 0.1, 50)
    # A point seen at time t in the base frame of that time: p_t = exp(t xi)^-1 p_ref.
    p_t = np.array(
        [
            np.linalg.solve(expm(hat(XI * tk)), np.append(p, 1.0))[:3]
            for p, tk in zip(p_ref, t, strict=True)
        ]
    )
    np.testing.assert_allclose(deskew_points(p_t, t, XI), p_ref, atol=1e-12)
    assert deskew_points(np.zeros((0, 3)), np.zeros(0), XI).shape == (0, 3)


def _max_errors(planes, truth):
    ang, off = [], []
    for p in planes:
        n, d = truth[p.truth_id]
        ang.append(np.degrees(np.arccos(np.clip(p.normal @ n, -1, 1))))
        off.append(abs(p.offset - d))
    return max(ang), max(off)


def test_moving_rig_is_exact_only_when_deskewed():
    scene = default_scene()
    truth = planes_in_base(scene)
    scan = scan_rig(scene, twist=XI)
    fixed = extract(scan, twist=XI).planes
    assert {p.truth_id for p in fixed} >= {0, 2, 4}
    ang, off = _max_errors(fixed, truth)
    assert ang < 1e-6 and off < 1e-6
    raw = extract(scan).planes  # no deskew: sweeps smeared over 0.1 s of motion
    if raw:
        ang_raw, off_raw = _max_errors(raw, truth)
        assert max(ang_raw, off_raw) > 1e-3
