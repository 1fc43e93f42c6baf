"""Seeds that share a trace on different planes: the worse fit waits (seedconflicts)."""

from __future__ import annotations

import numpy as np

from planodom.extraction.rig2d.seedconflicts import dominance, release


def _seeds(pairs, fit, is_l=None, n_traces=4, may_wait=None):
    i = np.array([a for a, _ in pairs], dtype=np.int64)
    j = np.array([b for _, b in pairs], dtype=np.int64)
    is_l = np.zeros(len(pairs), dtype=np.bool_) if is_l is None else np.array(is_l)
    member = np.zeros((len(pairs), n_traces), dtype=np.bool_)
    wait = np.ones(len(pairs), dtype=np.bool_) if may_wait is None else np.array(may_wait)
    for s, (a, b) in enumerate(pairs):
        member[s, a] = member[s, b] = True
    return i, j, np.array(fit, dtype=float), is_l, wait, member


def test_worse_fit_of_two_alternatives_waits():
    # trace 0 pairs with trace 1 (gap 1 noise unit) or trace 2 (3 units), on two planes
    i, j, fit, is_l, wait, member = _seeds([(0, 1), (0, 2), (1, 3)], [1.0, 3.0, 0.5])
    dom, n_dom = dominance(i, j, fit, is_l, wait, member)
    assert dom[1, 0] and not dom[0, 1]
    # (1, 3) fits better than (0, 1) and shares trace 1: (0, 1) waits too
    assert dom[0, 2]
    assert n_dom.tolist() == [1, 1, 0]


def test_seeds_of_one_plane_do_not_conflict():
    i, j, fit, is_l, wait, member = _seeds([(0, 1), (0, 2)], [1.0, 3.0])
    member[0, 2] = member[1, 1] = True  # each other's trace fits: one plane
    _, n_dom = dominance(i, j, fit, is_l, wait, member)
    assert n_dom.tolist() == [0, 0]


def test_an_l_seed_never_holds_a_crossing_one_back():
    i, j, fit, is_l, wait, member = _seeds([(0, 1), (0, 2)], [3.0, 1.0], is_l=[False, True])
    _, n_dom = dominance(i, j, fit, is_l, wait, member)
    assert n_dom.tolist() == [0, 0]  # (the L waits anyway: it is tried last)
    i, j, fit, is_l, wait, member = _seeds([(0, 1), (0, 2)], [1.0, 3.0], is_l=[False, True])
    _, n_dom = dominance(i, j, fit, is_l, wait, member)
    assert n_dom.tolist() == [0, 1]


def test_equal_fits_break_by_order_without_cycles():
    i, j, fit, is_l, wait, member = _seeds([(0, 1), (0, 2)], [2.0, 2.0])
    dom, n_dom = dominance(i, j, fit, is_l, wait, member)
    assert n_dom.tolist() == [0, 1] and dom[1, 0]


def test_release_frees_the_seeds_a_dead_one_held_back():
    i, j, fit, is_l, wait, member = _seeds([(0, 1), (0, 2), (0, 3)], [1.0, 2.0, 3.0])
    dom, n_dom = dominance(i, j, fit, is_l, wait, member)
    assert n_dom.tolist() == [0, 1, 2]
    alive = np.ones(3, dtype=np.bool_)
    was_alive = alive.copy()
    alive[0] = False
    release(dom, n_dom, was_alive, alive)
    assert n_dom.tolist() == [0, 0, 1] and not was_alive[0]


def test_a_seed_crossing_within_an_extent_never_waits():
    i, j, fit, is_l, wait, member = _seeds([(0, 1), (0, 2)], [1.0, 3.0], may_wait=[True, False])
    _, n_dom = dominance(i, j, fit, is_l, wait, member)
    assert n_dom.tolist() == [0, 0]
