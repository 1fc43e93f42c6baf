"""The platform a run assumes: the config's ``odometry.platform``, else the dataset's.

    cfg = with_platform(config, rig)    # what run_odometry and run_smoothing run with

``odometry.platform: auto`` (the default) takes what the dataset declares
(:attr:`planodom.rig.Rig.platform`: ``rig.yaml``'s ``platform``; the simulator's routes and
the KITTI readers say "vehicle"), else "unknown"; any other value overrides the dataset.
On a vehicle, the options of :data:`VEHICLE_OPTIONS` (those that assume a wheeled vehicle
and passed their rules) take their vehicle value unless the config sets them explicitly
(pydantic's ``model_fields_set``: a file, code or a ``--set`` names them), so a user's
value always wins. A hand-held or unknown platform changes nothing.
"""

from __future__ import annotations

from planodom.config import PlanodomConfig
from planodom.rig import Rig

#: ``odometry`` fields a vehicle switches on, with their vehicle value. Evidence in
#: docs/RESULTS.md: ``start_vehicle_twist``, GAPS6 (its rule on 2D-rig worlds 160-178);
#: ``gap_tilt``, TILT16 (its rule on 2D-rig worlds 580-598 and the built-in scenes).
VEHICLE_OPTIONS: dict[str, object] = {"start_vehicle_twist": True, "gap_tilt": "held"}


def resolved_platform(configured: str, declared: str | None) -> str:
    """The platform a run assumes: ``configured`` (``odometry.platform``) unless "auto",
    then ``declared`` (the dataset's, None: not stated -> "unknown")."""
    if configured != "auto":
        return configured
    return declared if declared is not None else "unknown"


def with_platform(config: PlanodomConfig, rig: Rig) -> PlanodomConfig:
    """``config`` with ``odometry.platform`` resolved against ``rig.platform``
    (:func:`resolved_platform`) and, on a vehicle, each of :data:`VEHICLE_OPTIONS` the
    config does not set explicitly at its vehicle value. Idempotent: the result sets
    every field it changed, so resolving it again (or the ``config.yaml`` a run writes
    of it) gives the same."""
    odometry = config.odometry
    platform = resolved_platform(odometry.platform, rig.platform)
    changes: dict[str, object] = {}
    if platform != odometry.platform:
        changes["odometry.platform"] = platform
    if platform == "vehicle":
        explicit = odometry.model_fields_set
        changes |= {f"odometry.{k}": v for k, v in VEHICLE_OPTIONS.items() if k not in explicit}
    return config.updated(changes, source="platform") if changes else config
