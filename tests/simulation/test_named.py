"""Simulating a random world by name: the hand-held walk of a seed, and where it is refused."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.errors import ConfigError
from planodom.simulation import simulate_named
from planodom.simulation.handheld import HandheldTrajectory
from planodom.simulation.random_world import random_world


def test_handheld_random_scene_walks_the_worlds_route():
    run = simulate_named("random", None, noise=0.0, seed=41, n_epochs=2, handheld=True)
    world = random_world(41, motion="handheld")
    assert isinstance(run.trajectory, HandheldTrajectory)
    assert np.allclose(run.poses, world.trajectory.poses(run.times))
    assert run.sensor_rig.to_dict() == world.sensor_rig.to_dict()
    assert len(run.scans[0]) > 1000


def test_handheld_refused_outside_random_scenes():
    with pytest.raises(ConfigError):
        simulate_named("paper-loop", handheld=True, n_epochs=2)


@pytest.mark.parametrize("scene", ["paper-loop", "random"])
@pytest.mark.parametrize("seed", [-1, 1.5, True])
def test_seed_that_numpy_refuses_is_a_config_error_naming_it(scene, seed):
    """numpy's generators take integers >= 0 only: a negative seed used to end in a
    ValueError traceback from deep inside numpy (``simulate --scene random --seed -1``)."""
    with pytest.raises(ConfigError, match=r"^seed: expected an integer >= 0, got .*--seed"):
        simulate_named(scene, None, seed=seed, n_epochs=2)
    with pytest.raises(ConfigError, match=r"^seed: expected an integer >= 0, got "):
        simulate_named(scene, None, noise=0.01, n_epochs=2, noise_seed=seed)


def test_another_noise_draw_keeps_the_world_and_redraws_the_noise():
    """``noise_seed`` keeps the world of ``seed`` (its route, rig and, without noise, every
    point) and draws another range noise: the points move by the noise's size only."""
    from planodom.simulation.named import simulate_random

    clean = simulate_random("random-outdoor", "isoclinal", 0.0, 3, n_epochs=2)
    own = simulate_random("random-outdoor", "isoclinal", 0.02, 3, n_epochs=2)
    other = simulate_random("random-outdoor", "isoclinal", 0.02, 3, n_epochs=2, noise_seed=9)
    again = simulate_random("random-outdoor", "isoclinal", 0.0, 3, n_epochs=2, noise_seed=9)
    assert np.array_equal(other.poses, own.poses)
    assert np.array_equal(again.scans[1].points, clean.scans[1].points)
    assert len(other.scans[1]) == len(own.scans[1]) == len(clean.scans[1])
    moved = np.linalg.norm(other.scans[1].points - own.scans[1].points, axis=1)
    assert 0.005 < np.median(moved) < 0.06  # two draws of 2 cm apart, not the same draw
