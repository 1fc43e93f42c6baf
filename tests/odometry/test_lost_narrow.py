"""An unresolved epoch extracted once more with narrow seeds
(:mod:`planodom.odometry.lost_narrow`, ``odometry.lost_narrow_seed_deg``), against the
true motion."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.spatial.transform import Rotation

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane
from planodom.odometry import PlaneOdometry
from planodom.odometry.relative import Status
from planodom.scan import Scan
from tests.pose_checks import pose_error

#: world planes n . p + d = 0: the ground, two walls and a slanted wall
WORLD = [([0, 0, 1.0], 1.0), ([0, -1.0, 0], 3.0), ([-1.0, 0, 0], 12.0), ([0.6, -0.8, 0], 6.0)]
STEP = np.eye(4)  # the true step of every epoch: 0.5 m ahead, 5 cm left, 2 deg of yaw
STEP[:3, :3] = Rotation.from_euler("z", 2.0, degrees=True).as_matrix()
STEP[:3, 3] = [0.5, 0.05, 0.0]
LOST = 2  # the epoch whose walls only narrow seeds find
N = 5


def _truth(k: int) -> np.ndarray:
    return np.linalg.matrix_power(STEP, k)


def _planes_of(k: int, narrow_deg: float) -> list[Plane]:
    """Epoch ``k``'s true planes in its base frame (0.01 deg, 1 mm): all of them, but at
    epoch ``LOST`` only the ground unless narrow seeds are on (its walls marked narrow)."""
    s = np.radians(0.01)
    cov = np.diag([s**2 / 2, s**2 / 2, s**2 / 2, 1e-6])
    T_world_k = _truth(k)
    out = []
    for i, (n, d) in enumerate(WORLD):
        narrow = k == LOST and i > 0
        if narrow and narrow_deg <= 0:
            continue
        world = Plane(np.array(n), d, cov, 0.9, truth_id=i, narrow=narrow)
        out.append(world.transformed(np.linalg.inv(T_world_k)))
    return out


def _run(deg: float) -> tuple[PlaneOdometry, list[tuple[int, float]]]:
    """Five epochs through a stub extractor (epoch index in the scan's first point), and
    the (epoch, narrow_seed_last_deg) of every extraction."""
    calls: list[tuple[int, float]] = []

    def extractor(scan, config, twist=None, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        k = int(scan.points[0, 0])
        calls.append((k, config.narrow_seed_last_deg))
        return _planes_of(k, config.narrow_seed_last_deg)

    changes = {"odometry.lost_narrow_seed_deg": deg, "odometry.pipeline": "wocsc"}
    config = PlanodomConfig().updated(changes)
    odo = PlaneOdometry(config, extractor=extractor)
    for k in range(N):
        odo.register_epoch(Scan(np.full((4, 3), float(k))), time=0.1 * k)
    return odo, calls


def test_off_leaves_the_epoch_unresolved_and_never_asks_for_narrow_seeds() -> None:
    odo, calls = _run(0.0)
    assert odo.results[LOST].status is Status.UNRESOLVED
    assert all(deg == 0.0 for _, deg in calls)


def test_on_resolves_it_at_the_true_step_and_touches_no_resolved_epoch() -> None:
    off, _ = _run(0.0)
    odo, calls = _run(0.5)
    assert odo.results[LOST].status is not Status.UNRESOLVED
    for k in range(1, N):  # every step at the truth
        T_step = np.linalg.inv(odo.poses[k - 1]) @ odo.poses[k]
        rot, xyz = pose_error(T_step, STEP)
        assert np.degrees(rot) < 1e-3 and xyz < 1e-3, k
    # narrow seeds are asked for at the lost epoch only, after its own extractions
    assert {k for k, deg in calls if deg > 0} == {LOST}
    assert calls[-1][0] != LOST  # the later epochs are extracted as by default
    for k in range(LOST):  # the epochs before it are the default's, bit for bit
        assert np.array_equal(odo.poses[k], off.poses[k])


@pytest.mark.parametrize("bad", [-0.1, 91.0, float("nan")])
def test_a_bad_value_is_named_at_load(bad: float) -> None:
    with pytest.raises((ConfigError, ValidationError), match="lost_narrow_seed_deg"):
        PlanodomConfig().updated({"odometry.lost_narrow_seed_deg": bad})
