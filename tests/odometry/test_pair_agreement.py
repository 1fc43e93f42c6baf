"""``agreeing_pairs`` gives the solver's former numpy verdicts, bit for bit."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

import planodom.odometry.pair_agreement as pair_agreement
from planodom.geometry import row_norms
from planodom.odometry.pair_agreement import agreeing_pairs


def _former(pn, cn, pp, cp, R, c) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The solver's expression before SPEED2D8 (the oracle)."""
    e1 = row_norms(pn[pp[:, 0]] - cn[cp[:, 0]] @ R.T)
    e2 = row_norms(pn[pp[:, 1]] - cn[cp[:, 1]] @ R.T)
    return (e1 <= c) & (e2 <= c)


def _case(rng: np.random.Generator, k: int = 6, m: int = 30):  # type: ignore[no-untyped-def]
    """Unit normals of two epochs related by ``R`` plus noise of 0-10 deg, random pairs."""
    R = Rotation.random(random_state=rng).as_matrix()
    cn = rng.standard_normal((k, 3))
    cn /= np.linalg.norm(cn, axis=1, keepdims=True)
    pn = cn @ R.T + rng.uniform(0, 0.2) * rng.standard_normal((k, 3))
    pn /= np.linalg.norm(pn, axis=1, keepdims=True)
    pp, cp = rng.integers(0, k, (m, 2)), rng.integers(0, k, (m, 2))
    return pn, cn, pp, cp, R


def test_verdicts_equal_the_former_expressions() -> None:
    rng = np.random.default_rng(31)
    for _ in range(300):
        pn, cn, pp, cp, R = _case(rng)
        for c in (0.01, 0.05, 0.2, 2.0):
            got = agreeing_pairs(pn, cn, pp, cp, R, c)
            np.testing.assert_array_equal(got, _former(pn, cn, pp, cp, R, c))


def test_a_chord_on_a_pairs_own_distance_goes_to_numpy() -> None:
    """Chords equal to one pair's distance (and one ulp either side): numpy decides."""
    rng = np.random.default_rng(32)
    for _ in range(100):
        pn, cn, pp, cp, R = _case(rng)
        e = float(row_norms(pn[pp[:1, 0]] - cn[cp[:1, 0]] @ R.T)[0])
        for c in (e, np.nextafter(e, 0.0), np.nextafter(e, 4.0)):
            got = agreeing_pairs(pn, cn, pp, cp, R, c)
            np.testing.assert_array_equal(got, _former(pn, cn, pp, cp, R, c))


def test_the_compiled_distances_decide_outside_the_band(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Fails when the compiled distances are wrong: with no band they decide alone."""
    monkeypatch.setattr(pair_agreement, "_GUARD", 0.0)
    monkeypatch.setattr(pair_agreement, "numpy_agreeing", None)  # never called
    rng = np.random.default_rng(33)
    for _ in range(100):
        pn, cn, pp, cp, R = _case(rng)
        for c in (0.05, 0.2):
            got = agreeing_pairs(pn, cn, pp, cp, R, c)
            np.testing.assert_array_equal(got, _former(pn, cn, pp, cp, R, c))


def test_no_pairs_and_non_finite_normals() -> None:
    rng = np.random.default_rng(34)
    pn, cn, pp, cp, R = _case(rng)
    assert agreeing_pairs(pn, cn, pp[:0], cp[:0], R, 0.1).shape == (0,)
    cn[cp[0, 0]] = np.nan
    got = agreeing_pairs(pn, cn, pp, cp, R, 0.1)
    np.testing.assert_array_equal(got, _former(pn, cn, pp, cp, R, 0.1))
    assert not got[0]
