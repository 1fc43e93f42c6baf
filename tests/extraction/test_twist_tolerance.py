"""The 2D-rig path with an uncertain twist: the tolerances grow by the smear a twist
error leaves (``twist_rate_sigma_deg_s``, ``twist_speed_sigma_mps``)."""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.extraction.rig2d.windows import twist_smear
from planodom.geometry import invert_transform, se3_log
from planodom.scan import Scan


def test_twist_smear_is_half_the_span_times_the_displacement_rate():
    # points 10 m away (median), times over 0.2 s: (0.3 m/s + 0.01 rad/s x 10 m) x 0.1 s
    pts = np.array([[10.0, 0, 0], [0, 10.0, 0], [6.0, 8.0, 0], [0, 0, 30.0], [1.0, 0, 0]])
    scan = Scan(points=pts, t=np.array([0.0, 0.05, 0.1, 0.15, 0.2]))
    assert np.isclose(twist_smear(scan, pts, 0.01, 0.3), 0.1 * (0.3 + 0.01 * 10.0))
    assert twist_smear(scan, pts, 0.0, 0.0) == 0.0
    assert twist_smear(Scan(points=pts), pts, 0.01, 0.3) == 0.0  # no times: no smear


def _true_planes(planes, truth) -> int:
    """How many ``planes`` lie on their true wall (1.5 deg, 3 cm)."""
    ids = list(truth.ids)
    good = 0
    for p in planes:
        if p.truth_id in ids:
            j = ids.index(p.truth_id)
            cos = float(p.normal @ truth.normal[j])
            s = 1.0 if cos >= 0 else -1.0
            off = abs(p.offset - s * truth.offset[j])
            good += bool(abs(cos) >= np.cos(np.radians(1.5)) and off <= 0.03)
    return good


def test_a_slightly_wrong_twist_keeps_the_walls_when_its_uncertainty_is_given():
    """World 8 (5 Hz epochs, 3.6 m/s): deskewed with a velocity 0.2 m/s off, the walls
    smear by up to 2 cm each side of their planes and most are lost against the 2 cm
    floor; with that uncertainty declared they are found again, on their true walls (the
    oracle's fits at the epoch time), and the true twist loses nothing."""
    from planodom.oracle import epoch_moments
    from planodom.simulation.random_world import random_world, simulate_world, world_fields

    k = 26
    world = random_world(8, rig="rig2d")
    full = simulate_world(world, 0.0, n_epochs=k + 1, all_fields=True)
    scan = world_fields(world, full)[k]
    t0 = full.times[k]
    T0, T1 = world.trajectory.poses(np.array([t0, t0 + 0.01]))
    twist = se3_log(invert_transform(T0) @ T1) / 0.01
    truth = epoch_moments(full.scans[k], world.trajectory, t0)
    exact = ExtractionConfig(twist_rate_sigma_deg_s=0.0, twist_speed_sigma_mps=0.0)
    sure = ExtractionConfig(twist_rate_sigma_deg_s=0.5, twist_speed_sigma_mps=0.5)
    n_true = _true_planes(extract(scan, exact, twist=twist).planes, truth)
    assert n_true >= 8
    assert _true_planes(extract(scan, sure, twist=twist).planes, truth) >= n_true
    wrong = twist + np.r_[0, 0, 0, 0.2, 0, 0]
    assert _true_planes(extract(scan, exact, twist=wrong).planes, truth) <= n_true - 3
    assert _true_planes(extract(scan, sure, twist=wrong).planes, truth) >= n_true - 1
