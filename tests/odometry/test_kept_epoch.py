"""What the streaming odometry keeps of an epoch (:mod:`planodom.odometry.kept_epoch`): which
epoch can be a reference."""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe, square_polygon

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, PlaneSupport, invert_transform, transform_from_rpy_xyz
from planodom.odometry import PlaneOdometry, Status
from planodom.odometry.kept_epoch import KeptEpoch
from planodom.planes import PlaneSet


def plane(normal, centroid, half: float = 3.0, truth_id: int = -1) -> Plane:  # noqa: ANN001
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    c = np.asarray(centroid, float)
    support = PlaneSupport(c, square_polygon(c, n, half), 200)
    return Plane(n, float(-n @ c), confidence=0.8, support=support, truth_id=truth_id)


def kept(planes: list[Plane]) -> KeptEpoch:
    return KeptEpoch(0, planes, PlaneSet.from_planes(planes))


def tilted(angle_deg: float) -> list[float]:
    """A unit normal ``angle_deg`` degrees from the ground's (0, 0, 1), towards x."""
    a = np.radians(angle_deg)
    return [np.sin(a), 0.0, np.cos(a)]


@pytest.mark.parametrize(
    ("angles_deg", "expected"),
    [
        ([], False),
        ([0.0], False),
        ([0.0, 0.0], False),  # one ground split in two groups
        ([0.0, 14.0], False),  # within association.parallel_angle_deg (15)
        ([0.0, 16.0], True),
        ([0.0, 90.0], True),  # the ground and a wall
        ([0.0, 166.0], False),  # near-opposite normals: parallel too
        ([0.0, 0.5, 164.0], True),
    ],
)
def test_a_pair_is_two_normals_outside_the_parallel_angle(angles_deg, expected):
    """Closed form: a non-parallel pair is two normals between 15 and 165 degrees apart."""
    planes = [plane(tilted(a), [0.0, 0.0, -1.0]) for a in angles_deg]
    assert kept(planes).has_pair(PlanodomConfig().association) is expected


def test_an_epoch_of_parallel_planes_is_not_the_next_epochs_reference():
    """World 192 at 2 cm (issue 11): the ground split in two planes by the extraction made
    an epoch with "two planes" the next one's reference; no pair can be associated against
    it, so the next epoch, which sees the ground and a wall again, was unresolved. Now it
    is associated with the last epoch that has a pair, and measured to the truth."""
    ground = plane([0, 0, 1], [5, 0, -1.5], 8)
    ground_far = plane([0, 0, 1], [12, 3, -1.5], 3)  # the same plane, another group
    walls = [plane([-1, 0, 0], [20, 0, 0.5], 4), plane([0, -1, 0], [8, 6, 0.5], 4),
             plane([0.6, 0.8, 0], [-3, -6, 0.5], 4)]  # fmt: skip
    poses = [transform_from_rpy_xyz(0.0, 0.0, 0.02 * k, 0.3 * k, 0.01 * k, 0.0) for k in range(6)]
    odo = PlaneOdometry(PlanodomConfig.from_dict({"odometry": {"pipeline": "wocsc"}}))
    for k, T in enumerate(poses):
        seen = [ground, ground_far] if k == 3 else [ground, *walls]
        odo.register_planes(observe(seen, T), time=0.1 * k)
    assert odo.results[3].status is Status.UNRESOLVED  # nothing to pair at epoch 3
    assert odo.results[4].prev == 2  # not epoch 3
    assert odo.results[4].status is Status.OK
    truth = invert_transform(poses[0]) @ poses[4]
    np.testing.assert_allclose(odo.poses[4], truth, atol=1e-6)


def test_has_pair_follows_the_planes_and_the_angle_it_is_asked_with():
    """The answer is remembered per plane set: new planes (a refresh) and another
    ``parallel_angle_deg`` are judged again, against the closed form (a pair is two normals
    more than the angle apart); the planes brought back judge as before."""
    association = PlanodomConfig().association
    epoch = kept([plane(tilted(0.0), [0, 0, -1]), plane(tilted(20.0), [0, 0, -1])])
    assert epoch.has_pair(association)  # 20 deg apart, the default angle 15
    wide = association.model_copy(update={"parallel_angle_deg": 25.0})
    assert not epoch.has_pair(wide) and epoch.has_pair(association)
    old = (epoch.planes, epoch.plane_set)
    flat = [plane(tilted(0.0), [0, 0, -1]), plane(tilted(3.0), [2, 0, -1])]
    epoch.planes, epoch.plane_set = flat, PlaneSet.from_planes(flat)
    assert not epoch.has_pair(association)
    epoch.planes, epoch.plane_set = old
    assert epoch.has_pair(association)
    epoch.planes = epoch.planes[:1]  # one plane left in the list: no pair
    assert not epoch.has_pair(association)
