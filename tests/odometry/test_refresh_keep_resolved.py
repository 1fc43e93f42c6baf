"""``odometry.refresh_keep_resolved``: a deskewing refinement made against a reference
extracted again with its twist is undone (the reference's old planes brought back, the
estimate before it kept) only when it left a resolved epoch unresolved
(:func:`planodom.odometry.deskew.register_deskewed`)."""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe, world_planes

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.geometry import Plane, invert_transform, se3_exp, transform_from_rpy_xyz
from planodom.odometry import PlaneOdometry
from planodom.odometry.deskew import EpochEstimate, register_deskewed
from planodom.odometry.relative import RelativePose, Status
from planodom.planes import PlaneSet
from planodom.scan import Scan

DT = 0.1
TRUE = np.array([0.0, 0.0, 0.3, 3.0, 0.2, 0.0])  # rad/s, m/s


def _estimate(twist: np.ndarray | None, status: Status) -> EpochEstimate:
    planes = [Plane(np.array([1.0, 0, 0]), -5.0), Plane(np.array([0, 0, 1.0]), 0.0)]
    step = se3_exp(TRUE * DT)
    rel = RelativePose(step, None, status)
    return EpochEstimate(planes, PlaneSet.from_planes(planes), twist, rel, step, planes)


@pytest.mark.parametrize(
    ("keep", "guard", "refined", "restored"),
    [
        (True, False, Status.UNRESOLVED, True),  # the fix: the resolved estimate kept
        (True, False, Status.DEGENERATE, False),  # worse but resolved: kept as before
        (False, False, Status.UNRESOLVED, False),  # off: today's rule, the refinement kept
        (False, True, Status.DEGENERATE, True),  # the broader guard undoes any worse one
    ],
)
def test_the_keep_decision_after_a_refreshed_reference(keep, guard, refined, restored):
    """The epoch resolves (OK) without a twist; deskewed with its own twist, against the
    reference extracted again with it, it is ``refined``. Expected from the rule: the
    refinement is undone (reference restored once, the first OK estimate kept) exactly
    when ``restored``; otherwise the refinement is kept."""

    def model(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        return _estimate(None, Status.OK) if twist is None else _estimate(twist, refined)

    restores: list[int] = []
    config = OdometryConfig(
        deskew_iterations=1, refresh_keep_resolved=keep, reference_refresh_guard=guard
    )
    best = register_deskewed(
        None, DT, model, lambda t: True, config, 2, restore_reference=lambda: restores.append(1)
    )
    if restored:
        assert restores == [1]
        assert best.twist is None and best.relative.status is Status.OK
    else:
        assert restores == []
        assert best.twist is not None and best.relative.status is refined


@pytest.mark.parametrize("keep", [True, False])
def test_a_refresh_that_leaves_the_next_epoch_unresolved_is_undone(keep):
    """Through :class:`PlaneOdometry` (the option reaches the policy): epoch 0, extracted
    again with epoch 1's twist, finds only its first plane, and epoch 1 against it is
    unresolved. With the option epoch 0's planes come back and epoch 1 keeps its exact
    step (the truth); without it epoch 1 stays unresolved."""
    world = world_planes(np.random.default_rng(5), 10)
    poses = [
        transform_from_rpy_xyz(0.0, 0.0, 0.03 * k, 0.1 * k, 0.002 * k**2, 0.0) for k in range(3)
    ]
    planes = [observe(world, T) for T in poses]

    def extractor(scan, cfg, twist=None):
        k = int(scan.points[0, 0])
        return planes[k][:1] if (k == 0 and twist is not None) else planes[k]

    odo = PlaneOdometry(
        PlanodomConfig().updated(
            {
                "odometry.pipeline": "wocsc",
                "odometry.refresh_keep_resolved": keep,
                "odometry.start_refresh": False,
            }
        ),
        extractor=extractor,
    )
    for k in range(3):
        odo.register_epoch(Scan(np.full((2, 3), float(k)), t=[0.0, 0.05]), 0.1 * k)
    if keep:
        assert len(odo.planes[0]) == len(planes[0])
        assert odo.results[1].status is Status.OK
        truth = invert_transform(poses[0]) @ poses[1]
        np.testing.assert_allclose(odo.poses[1], truth, atol=1e-9)
    else:
        assert len(odo.planes[0]) == 1
        assert odo.results[1].status is Status.UNRESOLVED


def test_a_bad_value_is_refused_naming_the_key():
    from planodom.errors import ConfigError

    with pytest.raises(ConfigError, match="refresh_keep_resolved"):
        PlanodomConfig().updated({"odometry.refresh_keep_resolved": "maybe"})
