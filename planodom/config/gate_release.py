"""When the degenerate gate stops holding its prediction (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.retry_status` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class GateReleaseConfig(Section):
    """``odometry.degenerate_gate_release``: what overrules ``degenerate_gate``."""

    degenerate_gate_release: Literal["off", "agreeing"] = "off"
    """``degenerate_gate: bridge`` reports a degenerate step unresolved when its angular
    rate disagrees with the constant-velocity prediction, and bridges it with that
    prediction; the next step is then gated against the same held rate. Where the true
    rate changes (a slope's onset, a turn), every later degenerate step disagrees with it
    too and the gate holds a stale rate over a whole stretch (the 2D-rig world 604 at 6 mm:
    11 right degenerate steps bridged, their pitch errors growing 0.1 -> 0.35 deg a step;
    docs/RESULTS.md, RELEASE16). ``agreeing``: a degenerate step the gate would bridge is
    kept when its rate agrees (the same test, :meth:`planodom.odometry.twist_sigma.
    TwistUncertainty.consistent`) with the rate of the last step the gate bridged, with
    no accepted step between them: two successive measurements that agree with each other
    and not with the prediction overrule it, so a held rate that was wrong does not
    outlive two epochs, while a lone wild step (issue 11's world 6, 192 deg/s against 12)
    is still bridged. ``off`` (default): the gate as it is."""
