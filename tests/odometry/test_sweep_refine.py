"""The odometry on scans deskewed by the motion measured inside every epoch
(planodom.odometry.sweep_refine) at sigma = 0 in continuous motion, against the truth."""

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform, se3_log
from planodom.odometry import Status, run_odometry
from planodom.simulation.rigs import rig_from_name
from planodom.simulation.simulate import simulate
from planodom.simulation.trajectory import paper_loop_trajectory
from planodom.simulation.worlds import scene_from_name


def _rotation_errors_deg(run, sim):
    """Per resolved epoch: rotation error of its relative pose, degrees."""
    out = []
    for k, r in enumerate(run.results):
        if r is None or r.status is not Status.OK:
            continue
        truth = invert_transform(sim.poses[r.prev]) @ sim.poses[k]
        out.append(np.degrees(np.linalg.norm(se3_log(invert_transform(truth) @ r.T_prev_curr)[:3])))
    return np.array(out)


def test_sweep_refine_passes_take_the_streaming_error_down():
    """Paper loop, isoclinal rig, sigma = 0, continuous motion, 12 epochs: two passes
    leave the median rotation error of the resolved epochs at under a tenth of the
    streaming pass's (its constant twist), with every epoch still resolved."""
    sim = simulate(scene_from_name("paper-loop"), paper_loop_trajectory(),
                   rig_from_name("isoclinal"), n_epochs=12, noise_sigma=0.0,
                   motion="continuous")  # fmt: skip
    streaming = run_odometry(sim, PlanodomConfig(), sim.rig)
    config = PlanodomConfig().updated({"sweep_refine.passes": 2})
    refined = run_odometry(sim, config, sim.rig)
    before, after = _rotation_errors_deg(streaming, sim), _rotation_errors_deg(refined, sim)
    assert len(after) >= len(before)
    assert np.median(after) < 0.1 * np.median(before), (np.median(before), np.median(after))
    assert "sweep_refine" in refined.seconds


def test_sweep_refine_map_prior_and_guard_keep_the_gain_at_sigma_zero():
    """As above with the MAP estimate (``prior: twist``: the run's own twist change as the
    prior of the motion inside the epoch, the reference planes' fit errors as unknowns)
    and the guard: at sigma = 0 the planes' covariances are tiny and the gain stays; an
    epoch the guard hands back to the streaming pass has exactly its step."""
    sim = simulate(scene_from_name("paper-loop"), paper_loop_trajectory(),
                   rig_from_name("isoclinal"), n_epochs=12, noise_sigma=0.0,
                   motion="continuous")  # fmt: skip
    streaming = run_odometry(sim, PlanodomConfig(), sim.rig)
    changes = {"sweep_refine.passes": 2, "sweep_refine.prior": "twist",
               "sweep_refine.guard": "streaming"}  # fmt: skip
    refined = run_odometry(sim, PlanodomConfig().updated(changes), sim.rig)
    before, after = _rotation_errors_deg(streaming, sim), _rotation_errors_deg(refined, sim)
    assert len(after) >= len(before)
    assert np.median(after) < 0.1 * np.median(before), (np.median(before), np.median(after))
    for k in range(1, len(sim.poses)):
        if refined.results[k] is streaming.results[k]:
            step = invert_transform(refined.poses[k - 1]) @ refined.poses[k]
            own = invert_transform(streaming.poses[k - 1]) @ streaming.poses[k]
            assert np.allclose(step, own, atol=1e-12)
