"""The noise sigma of an epoch and the distance tolerances scaled by it.

``sigma`` is ``range_noise_m``, or the across-line noise estimated from the epoch's own
scan lines or rings when that is larger (``estimate_noise``); a tolerance is
``max(factor * sigma, floor)`` (:class:`planodom.config.ExtractionConfig`).
"""

from __future__ import annotations

from planodom.config import ExtractionConfig


def effective_noise(config: ExtractionConfig, estimate_m: float) -> float:
    """The noise sigma (m) the tolerances scale with: the configured range noise, or the
    noise estimated from the data when that is larger (and ``config.estimate_noise``)."""
    return noise_sigma(config.estimate_noise, config.range_noise_m, estimate_m)


def noise_sigma(estimate_noise: bool, range_noise_m: float, estimate_m: float) -> float:
    """:func:`effective_noise` from the two config fields it reads (m)."""
    return max(range_noise_m, estimate_m) if estimate_noise else range_noise_m


def member_tolerance(config: ExtractionConfig, sigma_m: float) -> float:
    """Distance (m) within which a point or trace belongs to a plane."""
    return max(config.member_sigma_factor * sigma_m, config.tolerance_floor_m)


def rms_limit(config: ExtractionConfig, sigma_m: float) -> float:
    """Largest RMS residual (m) of a plane's points (a plane must be flat to the noise)."""
    return max(config.max_rms_sigma_factor * sigma_m, config.rms_floor_m)
