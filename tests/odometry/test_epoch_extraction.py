"""One extraction of an epoch in the streaming odometry (planodom.odometry.epoch_extraction)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.geometry import Plane
from planodom.odometry import PlaneOdometry
from planodom.odometry.plane_deskew import twist_covariance
from planodom.scan import Scan

COV = np.diag([1e-6, 2e-6, 0.0, 4e-6])
D = np.arange(24, dtype=float).reshape(4, 6) / 100.0  # (n, d) per twist error over the span
TWIST = np.array([0.0, 0.0, 0.3, 4.0, 0.0, 0.0])
SPAN = 0.2


def _odometry(mode: str, pipeline: str = "wocsc") -> tuple[PlaneOdometry, list]:
    """An odometry whose extractor returns one plane with COV and D, recording its calls."""
    calls: list = []

    def extractor(scan, config, twist=None, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        calls.append((config.deskew_jacobian, twist))
        return [Plane(np.array([1.0, 0, 0]), 4.0, covariance=COV.copy(), deskew_jacobian=D)]

    changes = {"odometry.plane_deskew_noise": mode, "odometry.pipeline": pipeline}
    return PlaneOdometry(PlanodomConfig().updated(changes), extractor=extractor), calls


def _scan() -> Scan:
    t = np.linspace(0.0, SPAN, 50)
    return Scan(np.column_stack([np.full(50, -4.0), np.linspace(-2, 2, 50), np.zeros(50)]), t=t)


def test_twist_adds_the_deskewing_twists_error_through_the_planes_jacobian():
    odo, calls = _odometry("twist")
    sigma = (0.05, 0.3)
    planes, used = odo._extract(_scan(), TWIST, prior=sigma)
    J = D * SPAN
    np.testing.assert_allclose(planes[0].covariance, COV + J @ twist_covariance(sigma) @ J.T)
    assert used is TWIST and calls == [(True, TWIST)]  # the Jacobians were asked for


def test_change_sizes_it_by_the_runs_change_of_motion():
    odo, _ = _odometry("change")
    change = odo.twist_uncertainty.raw_change()  # nothing measured: the deskew tolerances
    cfg = PlanodomConfig().odometry
    np.testing.assert_allclose(
        change, [np.radians(cfg.deskew_rate_tolerance_deg_s), cfg.deskew_speed_tolerance_mps]
    )
    planes, _ = odo._extract(_scan(), TWIST, prior=(5.0, 5.0))  # the twist's sigma unused
    J = D * SPAN
    expected = COV + J @ twist_covariance((change[0], change[1])) @ J.T
    np.testing.assert_allclose(planes[0].covariance, expected)


@pytest.mark.parametrize(
    ("mode", "pipeline", "twist", "prior"),
    [
        ("off", "wocsc", TWIST, (0.05, 0.3)),  # the default
        ("twist", "map", TWIST, (0.05, 0.3)),  # the plane map has its own deskew_variance
        ("twist", "wocsc", None, (0.05, 0.3)),  # not deskewed
        ("twist", "wocsc", TWIST, None),  # no sigma known (deskewed by a given model)
    ],
)
def test_nothing_is_added_when_off_on_the_map_or_without_a_twist_or_its_sigma(
    mode, pipeline, twist, prior
):
    odo, _ = _odometry(mode, pipeline)
    if pipeline == "map":
        odo._start_map(None)
        assert not odo.pairwise
    planes, _ = odo._extract(_scan(), twist, prior=prior)
    assert np.array_equal(planes[0].covariance, COV)
