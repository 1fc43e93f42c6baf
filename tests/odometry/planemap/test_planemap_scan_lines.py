"""PlaneMapOdometry on a swaying sensor whose plane list holds single scan lines.

A spinning lidar's line at elevation ``e`` across facades at different depths lies on the
laser's own cone (range noise moves each point along its ray, within the cone), so it
fits as a thin, nearly level "plane" fixed to the sensor: registered, such planes say the
roll and pitch never change (procedural world 29 at 2 cm). ``planemap.min_rows: 2``
leaves them out.
"""

from __future__ import annotations

import numpy as np
from planemap_factory import plane_points, planes_of
from scipy.spatial.transform import Rotation

from planodom.config import PlanodomConfig
from planodom.odometry.planemap import PlaneMapOdometry

GRADE = 0.03
N_GROUND = np.array([-GRADE, 0.0, 1.0]) / np.hypot(GRADE, 1.0)
SECTORS = np.arange(-180, 180, 30)
# Two vertical facades per 30 deg sector (azimuth of the normal, distance from the origin).
FACADES = np.random.default_rng(99).uniform(20.0, 50.0, (len(SECTORS), 2))


def world_pose(k: int) -> np.ndarray:
    """Driving up a 3 % slope at 0.18 m per scan, turning, with roll and pitch sway."""
    T = np.eye(4)
    rpy = [0.8 * np.sin(0.3 * k), 0.6 * np.cos(0.25 * k), 2.0 * k]
    T[:3, :3] = Rotation.from_euler("xyz", rpy, degrees=True).as_matrix()
    T[:3, 3] = [0.18 * k, 0.0, 1.8 + GRADE * 0.18 * k]
    return T


def _rays(rng, az0_deg, width_deg, elev_deg, count):
    phi = np.radians(az0_deg + rng.uniform(0, width_deg, count))
    el = np.radians(elev_deg)
    return phi, np.stack([np.cos(el) * np.cos(phi), np.cos(el) * np.sin(phi),
                          np.full(count, np.sin(el))], axis=1)  # fmt: skip


def _ground(rng, T, noise):
    """Four sectors of five near rings each on the slope (one plane per sector)."""
    R, t = T[:3, :3], T[:3, 3]
    sets = []
    for az0 in (-45, 45, 135, 225):
        pts = []
        for e in (-14, -16, -18, -20, -22):
            _, u = _rays(rng, az0, 90, e, 60)
            s = -(t @ N_GROUND) / ((u @ R.T) @ N_GROUND) + noise * rng.standard_normal(60)
            pts.append(s[:, None] * u)
        sets.append(np.vstack(pts))
    return sets


def _lines(rng, T, noise):
    """Single scan lines at five elevations near level across the sectors' facades."""
    R, t = T[:3, :3], T[:3, 3]
    sets = []
    for i, az0 in enumerate(SECTORS):
        for e in (-1.0, -0.5, 0.5, 1.0, 1.5):
            phi, u = _rays(rng, az0, 28, e, 40)
            half = (phi >= np.radians(az0 + 14)).astype(int)
            az = np.radians(az0 + 7 + 15 * half)
            nf = np.stack([np.cos(az), np.sin(az), np.zeros(40)], axis=1)
            s = (FACADES[i, half] - nf @ t) / np.einsum("ij,ij->i", nf, u @ R.T)
            sets.append((s + noise * rng.standard_normal(40))[:, None] * u)
    return sets


def _walls(rng, T, noise):
    inv = np.linalg.inv(T)
    specs = [([1, 0, 0], 12.0, [-12, 0, 2]), ([0, 1, 0], 10.0, [3, -10, 2]),
             ([0, -1, 0], 11.0, [-3, 11, 2]), ([-1, 0, 0], 30.0, [30, 5, 2])]  # fmt: skip
    return [plane_points(rng, n, d, c, 15, 600, noise) @ inv[:3, :3].T + inv[:3, 3]
            for n, d, c in specs]  # fmt: skip


def _scan(k, noise=0.02):
    rng = np.random.default_rng(3 + k)
    T = world_pose(k)
    planes = planes_of(_walls(rng, T, noise), rows=20) + planes_of(_ground(rng, T, noise), rows=5)
    return planes + planes_of(_lines(rng, T, noise), rows=1)


def _tilt_errors_deg(min_rows, n=6):
    """(n - 1, 3) rotation-vector error of each estimated step (deg), and the true steps."""
    odo = PlaneMapOdometry(PlanodomConfig().updated({"planemap.min_rows": min_rows}))
    errors, steps = [], []
    for k in range(n):
        est = odo.estimate(_scan(k))
        odo.commit(est)
        if k:
            step = np.linalg.inv(world_pose(k - 1)) @ world_pose(k)
            E = np.linalg.inv(step) @ est.relative.T_prev_curr
            errors.append(Rotation.from_matrix(E[:3, :3]).as_rotvec())
            steps.append(Rotation.from_matrix(step[:3, :3]).as_rotvec())
    return np.degrees(errors), np.degrees(steps)


def test_single_scan_lines_left_out_the_tilt_steps_match_the_truth():
    errors, steps = _tilt_errors_deg(min_rows=2)
    assert np.abs(steps[:, :2]).max() > 0.15  # the sway is there to be measured
    assert np.abs(errors).max() < 0.03


def test_single_scan_lines_registered_freeze_the_tilt():
    """The failure the option removes: the lines' cones hold roll and pitch still (the
    estimated tilt step near zero, its error near minus the true step)."""
    errors, steps = _tilt_errors_deg(min_rows=1)
    assert np.abs(errors[:, :2] + steps[:, :2]).max() < 0.3 * np.abs(steps[:, :2]).max()


def test_lines_of_unknown_count_are_used():
    """``n_rows`` 0 (lines unknown) is not a single line: such planes stay in."""
    planes = planes_of(_walls(np.random.default_rng(0), np.eye(4), 0.0), rows=0)
    odo = PlaneMapOdometry(PlanodomConfig().updated({"planemap.min_rows": 2}))
    assert len(odo.estimate(planes).used) == len(planes)
