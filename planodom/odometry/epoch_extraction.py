"""One extraction of an epoch in the streaming odometry (:meth:`PlaneOdometry._extract`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planodom.geometry import Plane
from planodom.odometry.coplanar import coplanar_by
from planodom.odometry.extractor import default_extractor
from planodom.odometry.plane_deskew import with_deskew_noise
from planodom.odometry.seed_extraction import seed_extraction
from planodom.odometry.twist_sigma import TwistSigma, widened
from planodom.scan import Scan

if TYPE_CHECKING:
    from planodom.odometry.odometry import PlaneOdometry


def extract_epoch(
    odo: PlaneOdometry, scan: Scan, twist: np.ndarray | None, sigma: TwistSigma | None = None,
    prior: TwistSigma | None = None,
) -> tuple[list[Plane], np.ndarray | None]:  # fmt: skip
    """The planes of ``scan`` deskewed with ``twist`` (None: not deskewed) by ``odo``'s
    extractor, whose error is taken to be ``sigma`` (rad/s, m/s; None: the extraction
    config's), and the twist used: ``twist``, or with ``odometry.deskew_twist: coplanar``
    the one fit to the planes with ``twist`` as the prior of sigma ``prior``
    (:mod:`.coplanar`). With ``odometry.plane_deskew_noise`` (pairwise pipelines; an
    epoch deskewed with a twist of known sigma ``prior``) the planes' covariances hold the
    error of a twist of sigma ``prior`` (``twist``) or of the run's change of motion over
    an epoch (``change``, :meth:`.TwistUncertainty.raw_change`), :mod:`.plane_deskew`."""
    if odo.extractor is None:
        odo.extractor = default_extractor()
    config = seed_extraction(widened(odo.config.extraction, twist, sigma), len(odo.poses))
    if odo.acceleration is not None:  # odometry.map_lead_acceleration
        scan = odo.acceleration.accelerated(scan, twist)
    planes, used = None, twist
    if twist is not None and odo.config.odometry.deskew_twist == "coplanar":
        origins = odo.sensor_origins
        got = coplanar_by(odo.extractor, scan, odo.config, config, twist, prior, origins)
        if got is not None:  # None: not the default extractor
            planes, used = got.planes, got.twist
    if planes is None:
        kwargs = {} if odo.sensor_origins is None else {"sensor_origins": odo.sensor_origins}
        planes = list(odo.extractor(scan, config, twist=twist, **kwargs))
    mode = odo.config.odometry.plane_deskew_noise
    if mode != "off" and odo.pairwise and prior is not None:
        change = odo.twist_uncertainty.raw_change()
        size = prior if mode == "twist" else (float(change[0]), float(change[1]))
        planes = with_deskew_noise(planes, scan, used, size)
    return planes, used
