"""A refinement tried again against its reference extracted again (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class SplitReferenceConfig(Section):
    """Whether a refinement that merges split walls may extract its reference again."""

    split_reference: Literal["off", "split", "any"] = "off"
    """Streaming, pairwise pipelines: ``split``: an epoch's refinement with its own twist
    (:mod:`planodom.odometry.deskew`, step 2) whose status is worse than the estimate it
    was refined from, that splits fewer walls than it (planes beyond distinct surfaces,
    the association's margins) and was estimated against a reference whose walls are
    split, is estimated again against the reference extracted again with the
    refinement's twist (about the reference's own points' twist); the new pair is kept
    when better by status, then distinct surfaces, else the reference's planes come back
    (:mod:`planodom.odometry.split_reference`). ``any``: every refinement of a worse
    status so. Off by default: found on 2D-rig world 166 at 6 mm, epoch 74
    (docs/RESULTS.md, TURNLAG and RANKREF)."""
