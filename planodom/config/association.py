"""Configuration of data association (and the bounded number types the sections share)."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from planodom.config.section import Section

#: A finite number > 0 (NaN and inf fail).
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
#: An angle in (0, 180] degrees.
AngleDeg = Annotated[float, Field(gt=0, le=180)]
#: An angle in (0, 90) degrees (from horizontal, or between two directions up to sign).
AcuteDeg = Annotated[float, Field(gt=0, lt=90)]


class AssociationConfig(Section):
    """Lenient and strict data association (planodom.association).

    The absolute constraints assume a maximum motion between two consecutive epochs:
    ``max_translation_m`` and ``max_rotation_deg`` (the defaults allow 10 m/s and 200 deg/s
    at 10 Hz epochs). With a motion prior (the constant-velocity prediction) the bounds
    are ``prior_translation_m`` / ``prior_rotation_deg`` around the prior instead. A
    dataset with faster motion or a lower epoch rate must raise them (config file or
    ``rig.yaml``); when epoch k is associated with epoch k - delta, the streaming
    odometry multiplies the per-epoch bounds by delta.
    """

    parallel_angle_deg: AcuteDeg = 15.0
    """Plane pairs whose normals are closer than this (or to its opposite) are parallel."""
    dihedral_tol_deg: AngleDeg = 5.0
    """LDA: two pairs are candidates when their dihedral angles differ by at most this."""
    max_translation_m: Positive = 1.0
    """Assumed maximum translation between consecutive epochs, metres (no prior)."""
    max_rotation_deg: AngleDeg = 20.0
    """Assumed maximum rotation angle between consecutive epochs, degrees (no prior)."""
    max_tilt_deg: AngleDeg = 180.0
    """Bound on the relative tilt between two epochs (the angle between their base z
    axes), degrees, whatever the other bounds (180: none). Not multiplied by a gap's
    epochs; ``odometry.gap_tilt: held`` sets it to ``max_rotation_deg`` for a gap."""
    prior_translation_m: Positive = 0.3
    """Allowed deviation from the motion prior's translation, metres."""
    prior_rotation_deg: AngleDeg = 5.0
    """Allowed deviation from the motion prior's rotation, degrees."""
    normal_tol_deg: AngleDeg = 5.0
    """Margin for noise on a plane normal's direction, degrees (added to rotation bounds)."""
    offset_tol_m: Positive = 0.2
    """Margin for noise on plane offsets and pair reference points, metres."""
    overlap_margin_m: Positive = 1.0
    """Margin of the support-overlap test (bounding circles of the support polygons), m."""
    strict_normal_deg: AngleDeg = 3.0
    """SDA: maximum angle between a previous normal and a rotated current normal, degrees."""
    strict_offset_m: Positive = 0.15
    """SDA: margin on offset differences beyond the translation bound, metres."""
    min_line_verticality: Annotated[float, Field(gt=0, le=1)] = 0.2
    """Minimum |v_z| of a pair's unit intersection direction to define a reference point."""
