"""When a degenerate epoch is also extracted without a twist (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.gate_release` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class UntwistedTryConfig(Section):
    """``odometry.untwisted_try``: which suspect epochs step 1 of the deskewing policy
    extracts again without a twist (:mod:`planodom.odometry.deskew`)."""

    untwisted_try: Literal["suspect", "fewer_planes"] = "suspect"
    """Step 1 of the deskewing policy extracts a suspect epoch again without a twist (and
    with the trend's or the held twist): unresolved, degenerate, or with far fewer planes
    than the epoch before. ``suspect`` (default): all of them. ``fewer_planes``: a
    degenerate epoch (with not far fewer planes) only when it has fewer planes than the
    epoch before. The other tries are a rescue from a wrong twist, which loses planes; a
    degenerate epoch that kept every plane count of the epoch before is degenerate by its
    geometry (a straight street), as :func:`planodom.odometry.deskew.prefer_streaming`
    already reads it. Measured on the seen 2D-rig worlds 420, 424, 426, 432, 436
    and 440 at 2 cm (docs/RESULTS.md,
    SPEED2D17): of the 350 untwisted tries after a degenerate first extraction, the 229
    with as many planes as the epoch before or more were kept 24 times (7 of them OK); the
    121 with fewer, 63 times (38 OK)."""
