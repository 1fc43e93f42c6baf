"""The relative pose's own helpers (:mod:`planodom.odometry.relative`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from planodom.association import PairAssociations
from planodom.odometry.relative import RelativePose, SolverDiagnostics, Status, replaced


def _fields(obj: object) -> dict[str, object]:
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}  # type: ignore[arg-type]


def test_replaced_equals_dataclasses_replace():
    info = SolverDiagnostics("wocsc", PairAssociations.empty(), n_translation_pairs=3)
    rel = RelativePose(np.eye(4), np.eye(5), Status.DEGENERATE, diagnostics=info)
    changes = {"prev": 2, "curr": 5, "T_prev_curr": 2.0 * np.eye(4), "sigma_z": 0.1}
    ours, theirs = replaced(rel, **changes), dataclasses.replace(rel, **changes)
    assert type(ours) is RelativePose and ours is not rel
    assert _fields(ours).keys() == _fields(theirs).keys()
    for name, value in _fields(theirs).items():
        assert getattr(ours, name) is value  # the same objects: a shallow copy
    assert rel.prev == -1 and rel.sigma_z == np.inf  # the original unchanged
    info2 = replaced(info, used_prior=True)
    assert _fields(info2) == _fields(dataclasses.replace(info, used_prior=True))
    with pytest.raises(dataclasses.FrozenInstanceError):
        ours.prev = 3  # type: ignore[misc]


def test_replaced_refuses_a_name_that_is_no_field():
    rel = RelativePose(np.eye(4), None)
    with pytest.raises(TypeError, match="no field"):
        replaced(rel, previous=1)


def test_sources_are_the_sorted_distinct_rows_of_the_winning_pairs():
    """Against numpy's own ``np.unique(rows, axis=0)`` of the (prev, curr) rows, on pairs
    with shared planes (repeated rows), any order of indices, and the degenerate case
    (the rotation pair only)."""
    rng = np.random.default_rng(11)
    info0 = SolverDiagnostics("wocsc", PairAssociations.empty())
    for _ in range(200):
        rot, trans = rng.integers(0, 4, 4), rng.integers(0, 4, 4)
        info = replaced(info0, rotation_pair=rot, translation_pair=trans)
        for status, pairs in ((Status.OK, (rot, trans)), (Status.DEGENERATE, (rot,))):
            rows = np.concatenate([p.reshape(2, 2).T for p in pairs])
            got = info.sources(status)
            assert got is not None
            np.testing.assert_array_equal(got, np.unique(rows, axis=0))
            assert got.dtype == np.unique(rows, axis=0).dtype
    assert info0.sources(Status.OK) is None
