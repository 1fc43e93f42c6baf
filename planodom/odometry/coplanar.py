"""An epoch deskewed with the twist its own planes give (``odometry.deskew_twist: coplanar``).

The twist the odometry passes (predicted by constant velocity, or refined from the
epoch's step) describes the steps around the epoch, not the time its points cover: the
2D rig's sweeps come after the epoch's reference time, and a route that accelerates, or
whose yaw rate changes, leaves a deskewing error that is the whole of the 2D rig's error
at sigma = 0 (issue 11). Here the epoch is extracted with the twist passed, the twist
that makes each plane's inliers coplanar is fit with the one passed as its prior
(:func:`planodom.extraction.twist_fit.fit_twist`), and the epoch is extracted again
with it (after every fit by default; with ``odometry.coplanar_reextract: moved`` only when
the fitted twist moves the inliers beyond their noise, summed over all of them, from the
twist they were extracted with; otherwise those planes are the ones an extraction with
it would give, within their noise. On the 2D rig "moved" halves the time, the odometry's
figures unchanged within 1 %; the batch with loop closure is not, see the config).

The prior's information is that of the twist sigma the odometry's model gives the twist
passed (:mod:`planodom.odometry.twist_sigma`: the error of the step it was measured
from plus the change of the twist between epochs, rms of the run's successive twists);
an unknown sigma (inf) gives no information. The points' noise is the extraction's
(``extraction.range_noise_m``, or the epoch's own estimate when larger), at least 1 mm:
below it the model's own error, a twist constant over the epoch, dominates (0.2-0.9 mm
rms on the 2D-rig world 0 at sigma = 0, the true surfaces deskewed with the best
constant twist of each epoch).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from planodom.config import ExtractionConfig, OdometryConfig, PlanodomConfig
from planodom.extraction.pipeline import ExtractionResult, extract, extract_planes, refit
from planodom.extraction.twist_fit import TwistFit, fit_twist
from planodom.geometry import Plane
from planodom.scan import Scan

#: Floor of the point noise of the twist fit, m (module docstring).
POINT_SIGMA_FLOOR_M = 1e-3
#: Floor of the prior's sigmas (rad/s, m/s): a twist refined from a step is not exact.
PRIOR_SIGMA_FLOOR = (np.radians(0.05), 0.01)
#: ``odometry.coplanar_axes: tilt``: the twist's components kept at the prior (yaw rate,
#: horizontal velocity, base frame z up) and the information that holds them there
#: (rad/s, m/s)^-2: far above any the planes give.
HELD_AXES = (2, 3, 4)
HELD_INFORMATION = 1e12
#: ``odometry.coplanar_reextract: moved``: a Gauss-Newton step below this many standard
#: deviations of the twist ends the fit (the rest of the nonlinearity is far inside the
#: twist's own uncertainty).
STEP_SIGMAS = 0.1


@dataclass(frozen=True, eq=False)
class CoplanarExtraction:
    """The planes of an epoch deskewed with its fitted twist.

    Attributes:
        planes: the planes of the last extraction. twist: (6,) the twist it was
            deskewed with (rad/s, m/s; None: not deskewed). fit: the last twist fit
            (None: none was made).
    """

    planes: list[Plane]
    twist: np.ndarray | None
    fit: TwistFit | None


def prior_information(sigma: tuple[float, float] | None, scale: float = 1.0) -> np.ndarray:
    """(6, 6) diagonal information of a twist whose angular rate and linear velocity are
    off by ``sigma`` (rad/s, m/s) per the model of :mod:`.twist_sigma` (the sigma of the
    vector: a third of its square per axis), both sigmas times ``scale`` (> 0,
    ``odometry.coplanar_prior_scale``) after their floors; zeros for an unknown (inf or
    None) sigma."""
    info = np.zeros(6)
    if sigma is None:
        return np.diag(info)
    for block, s, floor in ((slice(0, 3), sigma[0], PRIOR_SIGMA_FLOOR[0]),
                            (slice(3, 6), sigma[1], PRIOR_SIGMA_FLOOR[1])):  # fmt: skip
        if np.isfinite(s):
            info[block] = 3.0 / (scale * max(float(s), floor)) ** 2
    return np.diag(info)


def coplanar_extraction(
    scan: Scan,
    config: PlanodomConfig,
    twist: np.ndarray | None,
    sigma: tuple[float, float] | None,
    sensor_origins: np.ndarray | None = None,
    extraction: ExtractionConfig | None = None,
) -> CoplanarExtraction:
    """Extract ``scan`` deskewed with ``twist`` (6,), fit the twist to its planes with
    ``twist`` as the prior of sigma ``sigma`` (rad/s, m/s; :func:`prior_information`),
    and extract again with the fit, ``odometry.coplanar_passes`` times (module
    docstring). ``twist`` None (the first epoch, no motion known yet): the first
    extraction is not deskewed and the prior is a zero twist of sigma ``sigma`` (a
    vehicle's plausible rates; not used by the odometry, see ``smoothing.
    odometry_deskew_twist``'s figures). ``extraction``: the extraction config to use (default
    ``config.extraction``; the odometry may widen its tolerances)."""
    ecfg = config.extraction if extraction is None else extraction
    ocfg = config.odometry
    moved_only = ocfg.coplanar_reextract == "moved"
    prior = None if twist is None else np.asarray(twist, dtype=float)
    reuse = moved_only and ocfg.coplanar_reuse and prior is not None
    last = _LAST.get(scan, ecfg, sensor_origins) if reuse else None
    if last is not None:  # the epoch again (the deskewing policy): start from its planes
        found, used = last
    else:
        found, used = extract(scan, ecfg, twist, sensor_origins), prior
    if scan.t is None:
        return CoplanarExtraction(found.planes, used, None)
    P = prior_information(sigma, ocfg.coplanar_prior_scale)
    if ocfg.coplanar_axes == "tilt":
        P[HELD_AXES, HELD_AXES] = HELD_INFORMATION
    prior, fit = np.zeros(6) if prior is None else prior, None
    found, used, fit = _passes(scan, ecfg, ocfg, found, used, prior, P, sensor_origins)
    if moved_only and ocfg.coplanar_reuse:
        _LAST.put(scan, ecfg, sensor_origins, found, used)
    return CoplanarExtraction(found.planes, used, fit)


def _passes(
    scan: Scan, ecfg: ExtractionConfig, ocfg: OdometryConfig, found: ExtractionResult,
    used: np.ndarray | None, prior: np.ndarray, P: np.ndarray,
    sensor_origins: np.ndarray | None,
) -> tuple[ExtractionResult, np.ndarray | None, TwistFit | None]:  # fmt: skip
    """``odometry.coplanar_passes`` of: fit the twist to the planes ``found`` (extracted
    with ``used``) with the prior ``prior`` (6,) of information ``P`` (6, 6), extract
    again with it; the last extraction, its twist and the last fit."""
    assert scan.t is not None
    moved_only, fit = ocfg.coplanar_reextract == "moved", None
    for _ in range(ocfg.coplanar_passes):
        if not found.inliers:
            break
        s = max(found.sigma_m, POINT_SIGMA_FLOOR_M)
        start = used if moved_only else None
        fit = fit_twist(
            scan.points, scan.t, found.inliers, prior, P, s, ocfg.coplanar_iterations,
            start=start, step_sigmas=STEP_SIGMAS if moved_only else 0.0,
            evaluate_solution=not moved_only,
        )  # fmt: skip
        if moved_only and not _moves(fit, used):
            break  # the planes found with ``used`` are those the fit's twist would give
        used = fit.twist
        if ocfg.coplanar_planes == "refit":
            found = refit(found, scan, ecfg, used, sensor_origins)
        else:
            found = extract(scan, ecfg, used, sensor_origins)
    return found, used, fit


class _LastExtraction:
    """The last extraction made by :func:`coplanar_extraction` (``coplanar_reextract:
    moved``) and the twist it was deskewed with, for the same scan (the identity of its
    points, held weakly as :mod:`planodom.extraction.memo`), an equal extraction config
    and the same sensor origins: the deskewing policy extracts an epoch again with a
    refined twist, and the fit on these planes with that twist as its prior says whether
    an extraction is needed at all (the planes only change where the twist moves them)."""

    def __init__(self) -> None:
        self._key: tuple[weakref.ref[np.ndarray], ExtractionConfig, object] | None = None
        self._value: tuple[ExtractionResult, np.ndarray | None] | None = None

    def get(
        self, scan: Scan, ecfg: ExtractionConfig, origins: np.ndarray | None
    ) -> tuple[ExtractionResult, np.ndarray | None] | None:
        if self._key is None:
            return None
        ref, cfg, org = self._key
        if ref() is scan.points and org is origins and cfg == ecfg:
            return self._value
        return None

    def put(
        self, scan: Scan, ecfg: ExtractionConfig, origins: np.ndarray | None,
        found: ExtractionResult, used: np.ndarray | None,
    ) -> None:  # fmt: skip
        self._key = (weakref.ref(scan.points), ecfg, origins)
        self._value = (found, used)


_LAST = _LastExtraction()


def _moves(fit: TwistFit, used: np.ndarray | None) -> bool:
    """Whether deskewing with ``fit.twist`` instead of ``used`` (None: not deskewed)
    moves the fit's inliers along their normals by more than their noise, summed over
    all of them (``fit.displacement_information``): below that no plane the epoch's
    extraction builds from them moves by a standard deviation of its own fit (each
    plane's share of the sum is smaller), and extracting the epoch again would give the
    same planes within their noise."""
    d = fit.twist - (np.zeros(6) if used is None else used)
    return bool(d @ fit.displacement_information @ d > 1.0)


def coplanar_by(
    extractor: Callable[..., object] | None,
    scan: Scan,
    config: PlanodomConfig,
    extraction: ExtractionConfig,
    twist: np.ndarray | None,
    sigma: tuple[float, float] | None,
    sensor_origins: np.ndarray | None,
) -> CoplanarExtraction | None:
    """:func:`coplanar_extraction` when ``extractor`` is the default one
    (:func:`planodom.extraction.extract_planes`, or a wrapper of it with a ``timed``
    method that adds up its time, as :func:`planodom.odometry.run.run_odometry` s);
    None for any other extractor (the fit needs the planes' inliers)."""
    base = getattr(extractor, "extractor", extractor)
    if base is not None and base is not extract_planes:
        return None
    timed = getattr(extractor, "timed", None)
    args = (scan, config, twist, sigma, sensor_origins, extraction)
    return timed(coplanar_extraction, *args) if timed is not None else coplanar_extraction(*args)
