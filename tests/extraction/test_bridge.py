"""A gap of the 2D-rig grouping bridged where one side's plane predicts the other
(:mod:`planodom.extraction.rig2d.bridge`, ``extraction.gap_bridge``), against the true
planes."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from planodom.config import ExtractionConfig
from planodom.errors import ConfigError
from planodom.extraction import extract
from planodom.scan import Scan

SIGMA = 0.003
CEILING_M = 2.5


def _ceiling(step_m: float = 0.0, near_lines: int = 3) -> Scan:
    """A ceiling z = 2.5 m seen behind by ring 0 as ``near_lines`` parallel 8 m lines
    along y (three sweeps, at x = -18, -16, -14), and 30 m ahead by ring 1 as one 8 m line
    crossing them at 60 deg, ``step_m`` higher (0: one plane)."""
    rng = np.random.default_rng(5)
    s = np.linspace(-4.0, 4.0, 100)
    parts, rings = [], []
    for x in (-18.0, -16.0, -14.0)[:near_lines]:
        parts.append(np.column_stack([np.full_like(s, x), s, np.full_like(s, CEILING_M)]))
        rings.append(0)
    u = np.array([np.cos(np.radians(60.0)), np.sin(np.radians(60.0)), 0.0])
    ahead = np.array([16.0, 0.0, CEILING_M + step_m]) + s[:, None] * u
    parts.append(ahead)
    rings.append(1)
    pts = np.concatenate(parts)
    pts[:, 2] += rng.normal(0.0, SIGMA, len(pts))
    ring = np.repeat(np.array(rings, np.int32), len(s))
    t = np.concatenate([np.linspace(0.0, 0.004, len(s)) + 0.01 * k for k in range(len(rings))])
    t[ring == 1] -= t[ring == 1][0]
    return Scan(pts, ring=ring, t=t)


def _planes(scan: Scan, mode: str):
    cfg = ExtractionConfig(range_noise_m=SIGMA, gap_bridge=mode)
    return extract(scan, cfg, twist=np.zeros(6)).planes


def test_a_ceiling_seen_behind_and_far_ahead_is_one_true_plane():
    """The gap rule cuts the seed's far line (30 m) and no plane is left; bridged, the
    ceiling is one plane within 0.02 deg and 5 mm of the truth, with all four lines."""
    assert _planes(_ceiling(), "off") == []
    planes = _planes(_ceiling(), "predicted")
    assert len(planes) == 1
    p = planes[0]
    n = p.normal * np.sign(p.normal[2])
    assert np.degrees(np.arccos(min(1.0, n[2]))) < 0.02
    assert abs(abs(p.offset) - CEILING_M) < 0.005
    assert p.support is not None and p.support.n_points >= 390  # the far line too (robust refit)


def test_a_step_beyond_the_tolerance_is_not_bridged():
    """The far line 3 cm higher (two planes; within the seed test, beyond the 2 cm member
    tolerance of the near lines' plane there): no plane, as without the option."""
    assert _planes(_ceiling(step_m=0.03), "predicted") == []


def test_one_line_on_each_side_never_bridges():
    """With one near line the near piece has no spread across its line: it predicts
    nothing 30 m away, and the far line alone neither: no plane."""
    assert _planes(_ceiling(near_lines=1), "off") == []
    assert _planes(_ceiling(near_lines=1), "predicted") == []


@pytest.mark.parametrize("bad", ["on", "true", ""])
def test_a_bad_mode_is_refused_at_load(bad):
    with pytest.raises((ConfigError, ValidationError), match="gap_bridge"):
        ExtractionConfig(gap_bridge=bad)
