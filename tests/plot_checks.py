"""Checks that a written picture is a real plot, not an empty or single-colour image."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def assert_nontrivial_png(path: Path, min_bytes: int = 8_000, min_colours: int = 8) -> None:
    """``path`` is a PNG of more than ``min_bytes`` with several colours over its area."""
    import matplotlib.image

    assert path.is_file(), path
    assert path.stat().st_size > min_bytes, (path, path.stat().st_size)
    image = matplotlib.image.imread(path)
    assert image.ndim == 3 and min(image.shape[:2]) > 300, image.shape
    pixels = image[..., :3].reshape(-1, 3)
    colours = np.unique(np.round(pixels * 255).astype(np.uint8), axis=0)
    assert len(colours) >= min_colours, (path, len(colours))
    # not a mostly empty canvas: ink (non-white) in every quarter of the height
    ink = (pixels.reshape(image.shape[0], image.shape[1], 3) < 0.9).any(axis=2)
    for band in np.array_split(ink, 4, axis=0):
        assert band.any(), path
