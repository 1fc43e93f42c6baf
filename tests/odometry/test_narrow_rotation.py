"""Narrow planes give the rotation only when no other pair does (``odometry.narrow_rotation``,
:func:`planodom.odometry.rotation_planes.rotation_pairs`), checked against the pairs that
hold a marked plane."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from planodom.association import lenient_association
from planodom.config import ExtractionConfig, PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane
from planodom.odometry.rotation_planes import rotation_pairs
from planodom.planes import PlaneSet

OFF = ExtractionConfig()


def _room(narrow: list[bool]) -> list[Plane]:
    """Three walls and the ground (0.1 deg, 1 cm), marked narrow as ``narrow``."""
    normals = [[1.0, 0, 0], [0, 1.0, 0], [0.6, -0.8, 0], [0, 0, 1.0]]
    offsets = [4.0, 3.0, 6.0, 1.5]
    s = np.radians(0.1)
    cov = np.diag([s**2 / 2, s**2 / 2, s**2 / 2, 1e-4])
    return [
        Plane(np.array(n), d, cov, 0.9, narrow=m)
        for n, d, m in zip(normals, offsets, narrow, strict=True)
    ]


def test_pairs_with_a_narrow_plane_are_dropped_while_others_are_left() -> None:
    planes = PlaneSet.from_planes(_room([False, False, True, False]))
    assert planes.narrow is not None and planes.narrow.tolist() == [False, False, True, False]
    lda = lenient_association(planes, planes)
    holds = (lda.prev_pairs == 2).any(axis=1) | (lda.curr_pairs == 2).any(axis=1)
    assert holds.any() and not holds.all()
    assert rotation_pairs(planes, planes, lda, OFF) is lda  # narrow_last off
    kept = rotation_pairs(planes, planes, lda, OFF, narrow_last=True)
    assert len(kept) == int((~holds).sum())
    assert not (kept.prev_pairs == 2).any() and not (kept.curr_pairs == 2).any()
    # the rotations and weights travel with their pairs
    assert np.array_equal(kept.weights, lda.weights[~holds])


def test_narrow_pairs_stay_when_every_pair_holds_one() -> None:
    """A corridor's turn: every wall narrow, the ground alone is wide; every pair holds a
    narrow wall, so all of them give the rotation."""
    planes = PlaneSet.from_planes(_room([True, True, True, False]))
    lda = lenient_association(planes, planes)
    assert len(lda) and rotation_pairs(planes, planes, lda, OFF, narrow_last=True) is lda


def test_unmarked_sets_and_subsets_carry_the_marks() -> None:
    plain = PlaneSet.from_planes(_room([False] * 4))
    assert plain.narrow is None  # none marked: no array
    marked = PlaneSet.from_planes(_room([False, True, False, False]))
    assert marked.take(np.array([3, 1])).narrow.tolist() == [False, True]
    assert marked.transformed(np.eye(4)).narrow.tolist() == [False, True, False, False]
    moved = dataclasses.replace(_room([True] * 4)[0], offset=2.0)
    assert moved.narrow


def test_it_is_all_by_default_and_a_bad_value_names_the_field(tmp_path) -> None:
    assert PlanodomConfig().odometry.narrow_rotation == "all"
    (tmp_path / "c.yaml").write_text("odometry: {narrow_rotation: last}\n")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").odometry.narrow_rotation == "last"
    (tmp_path / "c.yaml").write_text("odometry: {narrow_rotation: first}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'odometry\.narrow_rotation'") as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)
