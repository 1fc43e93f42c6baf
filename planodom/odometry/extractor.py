"""The plane extractor the streaming odometry calls (:data:`Extractor`) and its default."""

from __future__ import annotations

from collections.abc import Callable

from planodom.geometry import Plane

#: ``extractor(scan, extraction_config, twist=..., [sensor_origins=...]) -> list[Plane]``
Extractor = Callable[..., list[Plane]]


def default_extractor() -> Extractor:
    """:func:`planodom.extraction.extract_planes`, imported when first needed."""
    from planodom.extraction import extract_planes

    return extract_planes
