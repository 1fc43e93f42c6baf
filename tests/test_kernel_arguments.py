"""The association's compiled kernels get one layout of their array arguments.

numba compiles one specialisation per argument type, and a read-only or strided array is
another type than a writeable C-contiguous one: a prior that arrives read-only made
``_lda_kernel`` compile a second time in the middle of a timed run (seconds of CPU on a
cold cache, a 2D-rig world measured at a fifth of its speed). The callers hand the
kernels writeable C-contiguous copies; these tests spy on the arguments.
"""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe, world_planes

import planodom.association as association
import planodom.consensus as consensus_module
from planodom.geometry import transform_from_rpy_xyz
from planodom.planes import PlaneSet


def _epochs() -> tuple[PlaneSet, PlaneSet, np.ndarray]:
    rng = np.random.default_rng(3)
    world = world_planes(rng, 6)
    T_w_a = transform_from_rpy_xyz(0.0, 0.0, 0.3, 1.0, 2.0, 0.0)
    T_ab = transform_from_rpy_xyz(0.0, 0.0, 0.05, 0.4, -0.1, 0.0)
    prev = PlaneSet.from_planes(observe(world, T_w_a))
    curr = PlaneSet.from_planes(observe(world, T_w_a @ T_ab))
    return prev, curr, T_ab


def _spy(monkeypatch: pytest.MonkeyPatch, module: object, name: str) -> list[tuple]:
    seen: list[tuple] = []
    kernel = getattr(module, name)

    def spy(*args):  # type: ignore[no-untyped-def]
        seen.append(args)
        return kernel(*args)

    monkeypatch.setattr(module, name, spy)
    return seen


def _plain(a: np.ndarray) -> bool:
    return bool(a.flags.c_contiguous and a.flags.writeable)


def test_a_read_only_prior_reaches_lda_writeable(monkeypatch: pytest.MonkeyPatch) -> None:
    prev, curr, T = _epochs()
    frozen = T.copy()
    frozen.flags.writeable = False
    seen = _spy(monkeypatch, association, "_lda_kernel")
    a = association.lenient_association(prev, curr, prior=frozen)
    b = association.lenient_association(prev, curr, prior=np.asfortranarray(T))
    assert len(a) > 0 and np.array_equal(a.curr_pairs, b.curr_pairs)
    assert all(_plain(args[10]) for args in seen)
    assert not frozen.flags.writeable  # the caller's array is left as it was


def test_a_strided_translation_reaches_sda_contiguous(monkeypatch: pytest.MonkeyPatch) -> None:
    prev, curr, T = _epochs()
    seen = _spy(monkeypatch, association, "sda_kernel")
    ij = association.strict_association(prev, curr, T[:3, :3], translation=T[:3, 3])
    assert len(ij) > 0 and len(seen) == 1
    assert all(_plain(args[9]) for args in seen)


def test_strided_groups_reach_the_consensus_contiguous(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(0)
    src = rng.normal(size=(6, 2))
    t = np.array([0.3, -0.2])
    groups = np.arange(12, dtype=np.int64)[::2]  # a strided view
    seen = _spy(monkeypatch, consensus_module, "_consensus_kernel")
    cand = np.vstack([t, t + 0.5, -t])
    result = consensus_module.consensus(
        cand, src, src - t, consensus_module.apply_negative_translation, groups=groups
    )
    assert result.best_index in (0, 2)  # the true translation, whichever sign convention
    assert seen and all(args[6].flags.c_contiguous for args in seen)
