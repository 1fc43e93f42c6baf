"""Which first extractions the deskewing policy tries to better (``odometry.untwisted_try``,
:func:`planodom.odometry.untwisted_try.suspect`), and the policy's tries with it."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import OdometryConfig
from planodom.geometry import Plane
from planodom.odometry.deskew import EpochEstimate, register_deskewed
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.untwisted_try import suspect
from planodom.planes import PlaneSet

DT = 0.1
PREDICTED = np.array([0.0, 0.0, 0.1, 2.0, 0.0, 0.0])


def _estimate(twist: np.ndarray | None, status: Status, n_planes: int) -> EpochEstimate:
    planes = [Plane(np.array([1.0, 0, 0]), -5.0 - k) for k in range(n_planes)]
    step = np.eye(4)
    rel = RelativePose(step, None, status)
    return EpochEstimate(planes, PlaneSet.from_planes(planes), twist, rel, step, planes)


@pytest.mark.parametrize(
    ("status", "n_planes", "previous", "few", "default", "fewer_planes"),
    [
        (Status.OK, 5, 5, False, False, False),
        (Status.OK, 1, 5, True, True, True),  # far fewer planes: suspect either way
        (Status.UNRESOLVED, 5, 5, False, True, True),
        (Status.UNRESOLVED, 9, 5, False, True, True),
        (Status.DEGENERATE, 4, 5, False, True, True),  # lost a plane
        (Status.DEGENERATE, 5, 5, False, True, False),  # as many as before
        (Status.DEGENERATE, 6, 5, False, True, False),
        (Status.DEGENERATE, 2, 0, False, True, False),  # no epoch before
    ],
)
def test_which_first_extractions_are_suspect(
    status, n_planes, previous, few, default, fewer_planes
):
    first = _estimate(PREDICTED, status, n_planes)
    assert suspect(first, few, previous, "suspect") is default
    assert suspect(first, few, previous, "fewer_planes") is fewer_planes


def _tries(config: OdometryConfig, previous: int, n_planes: int) -> list[object]:
    """The twists the policy extracted with, the first one degenerate with ``n_planes``
    and every other try (untwisted) degenerate with one plane more."""
    tried: list[object] = []

    def model(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        tried.append(None if twist is None else tuple(twist))
        return _estimate(twist, Status.DEGENERATE, n_planes + (twist is None))

    register_deskewed(PREDICTED, DT, model, lambda t: False, config, previous)
    return tried


def test_a_degenerate_epoch_with_as_many_planes_is_not_extracted_without_a_twist():
    default = OdometryConfig(deskew_iterations=0)  # step 1's tries alone
    fewer = OdometryConfig(deskew_iterations=0, untwisted_try="fewer_planes")
    # as many planes as the epoch before: the default tries without a twist, the option not
    assert _tries(default, 4, 4) == [tuple(PREDICTED), None]
    assert _tries(fewer, 4, 4) == [tuple(PREDICTED)]
    # a plane lost: both try without a twist
    assert _tries(default, 5, 4) == [tuple(PREDICTED), None]
    assert _tries(fewer, 5, 4) == [tuple(PREDICTED), None]
