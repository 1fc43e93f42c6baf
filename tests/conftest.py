"""Shared test settings: deterministic hypothesis profile, open3d importable everywhere."""

from __future__ import annotations

from hypothesis import HealthCheck, settings

import planodom._open3d  # noqa: F401  (loads libusb before any test imports open3d)

settings.register_profile(
    "planodom",
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("planodom")
