"""The RANSAC fallback's compiled draws and plane loop against numpy's ``Generator`` and
the per-plane loop in Python (:mod:`planodom.extraction.lidar.ransac`,
:mod:`planodom.extraction.lidar.candidates`)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.extraction.lidar import candidates as cmod
from planodom.extraction.lidar.cells import angular_cells, cell_members
from planodom.extraction.lidar.ransac import draw_samples, draw_stream, log_fail, seed_stream

from .synth_scans import default_scene, scan_lidar

#: Bounds drawn in turn: the smallest (the third column's bound is 1: no draw), usual
#: voxel counts, and bounds just over 2^31, where Lemire's method rejects about half of
#: the 32-bit draws (the rejection path), and the largest below 2^32.
_BOUNDS = [3, 4, 3000, 17, 3, 2**31 + 1, 5, 2**32 - 1, 1000, 3, 2**31 + 7, 250]


@pytest.mark.parametrize("seed", [0, 5, 123456789])
def test_draw_stream_is_numpys_generator(seed):
    words = seed_stream(seed, 50_000)
    rng = np.random.default_rng(seed)
    state = np.zeros(3, dtype=np.int64)
    for i, m in enumerate(_BOUNDS):
        n = 7 if i % 2 else 300  # odd counts of 32-bit draws: a pending half carried over
        np.testing.assert_array_equal(draw_stream(words, state, m, n), draw_samples(rng, m, n))
        assert state[2] == 0
    # the generator is where the stream is: its next draws are the stream's next ones
    np.testing.assert_array_equal(draw_stream(words, state, 99, 5), draw_samples(rng, 99, 5))


def test_draw_stream_says_when_the_words_run_out():
    state = np.zeros(3, dtype=np.int64)
    draw_stream(seed_stream(0, 10), state, 1000, 7)  # 21 draws from 20 halves
    assert state[2] == 1


def test_seed_stream_read_only_and_shared():
    a = seed_stream(3, 100)
    assert not a.flags.writeable and seed_stream(3, 100) is a
    np.testing.assert_array_equal(a, np.random.default_rng(3).bit_generator.random_raw(100))


def _python_loop(points, config, view, tol):
    """The RANSAC loop with numpy's generator and one :func:`_ransac_plane` call per
    plane from Python (the loop before it was compiled)."""
    n_az = int(np.ceil(360.0 / config.cluster_gap_deg))
    vox = np.asarray(
        cmod.o3d.geometry.PointCloud(cmod.o3d.utility.Vector3dVector(points))
        .voxel_down_sample(config.voxel_size_m)
        .points
    )
    vc = angular_cells(vox, view, config.cluster_gap_deg)
    pc = angular_cells(points, view, config.cluster_gap_deg)
    vox_az, pt_az = vc[:, 0] % n_az, pc[:, 0] % n_az
    pt_el, vox_el = np.ascontiguousarray(pc[:, 1]), np.ascontiguousarray(vc[:, 1])
    n_el = 1 + max(int(pt_el.max()), int(vox_el.max()))
    remaining = np.ones(len(vox), dtype=bool)
    taken = np.zeros(len(points), dtype=bool)
    min_vox = max(3, config.min_plane_points // 4)
    cols = (*cell_members(vox_az, vox_el, n_az, n_el), *cell_members(pt_az, pt_el, n_az, n_el))
    rng = np.random.default_rng(config.seed)
    out, n_rem = [], len(vox)
    for _ in range(config.max_planes):
        if n_rem < min_vox:
            break
        samples = draw_samples(rng, n_rem, config.ransac_iterations)
        n_rem, cand, bounds = cmod._ransac_plane(
            points, vox, tol, log_fail(config.ransac_probability), min_vox,
            config.min_plane_points, n_az, samples, vox_az, vox_el, n_el,
            remaining, taken, *cols,
        )  # fmt: skip
        if n_rem < 0:
            break
        out.extend(cand[bounds[k] : bounds[k + 1]] for k in range(len(bounds) - 1))
    return out


@pytest.mark.parametrize(
    ("sigma", "seed", "max_planes"), [(0.0, 0, 40), (0.02, 7, 40), (0.02, 1, 3)]
)
def test_compiled_loop_gives_the_python_loops_candidates(sigma, seed, max_planes):
    scan = scan_lidar(default_scene(), sigma=sigma, seed=seed, n_beams=16, n_azimuth=512)
    config = ExtractionConfig(seed=seed, max_planes=max_planes)
    view = np.array([0.0, 0.0, 1.8])
    got = cmod.ransac_candidates(scan.points, config, view, 0.05)
    want = _python_loop(scan.points, config, view, 0.05)
    assert len(want) >= min(max_planes, 4)
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


def test_compiled_loop_starts_again_with_a_longer_stream(monkeypatch):
    """A stream too short for the scan's draws: the loop runs the scan again with one
    twice as long until it suffices, with the same candidates."""
    scan = scan_lidar(default_scene(), sigma=0.02, seed=3, n_beams=16, n_azimuth=512)
    config = ExtractionConfig(seed=3)
    view = np.array([0.0, 0.0, 1.8])
    asked = []

    def short(seed, n_words):
        asked.append(n_words)
        return seed_stream(seed, max(n_words // 64, 1))

    monkeypatch.setattr(cmod, "seed_stream", short)
    got = cmod.ransac_candidates(scan.points, config, view, 0.05)
    assert len(asked) > 1 and asked[1] == 2 * asked[0]
    want = _python_loop(scan.points, config, view, 0.05)
    assert len(got) == len(want) >= 4
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)
