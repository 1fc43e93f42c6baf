"""What the 2D rig's noise estimate measures (a field of ``extraction``).

A base of :class:`planodom.config.extraction.ExtractionConfig`, kept in its own module
(that one is near the layout limit).
"""

from __future__ import annotations

from typing import Literal

from planodom.config.extraction_reuse import ReuseFields


class NoiseFields(ReuseFields):
    """How ``estimate_noise`` turns a 2D rig's scan lines into a noise sigma (a field of
    ``extraction``)."""

    noise_estimate: Literal["across", "range"] = "across"
    """2D rig, with ``estimate_noise`` and a sensor origin per ring: ``across`` (default):
    the noise across the scan lines (robust second differences), which is the range noise
    times the sine of the angle between ray and line, so below it wherever surfaces are
    seen obliquely (a simulated indoor lap at 2 cm: 1.2-1.4 cm), while a surface seen
    head-on scatters about its plane by the full range noise and fails a plane test scaled
    by that estimate (``max_rms_sigma_factor``). ``range``: each second difference divided
    by that sine, i.e. the range noise (:mod:`planodom.extraction.rig2d.rangenoise`; 2.0 cm
    on those laps). Off by default, measured on the 2D-rig worlds 140-178 (150 epochs,
    docs/RESULTS.md, BUILTIN2): at 2 cm median ATE 0.267 -> 0.117 m, unresolved epochs 80
    -> 48, rotation 0.216 -> 0.148 deg, but world 166 0.59 -> 2.22 m; at 6 mm (the
    configured noise is the simulated one) unresolved 50 -> 55: its rule fails."""
