"""``extraction.ransac_unjudged: seed``: the extractions made while the streaming odometry
registers its first two epochs refuse the RANSAC planes the agreement check cannot judge;
the later ones keep them (:mod:`planodom.odometry.seed_extraction`)."""

from __future__ import annotations

import numpy as np
from planes_factory import observe, world_planes

from planodom.config import ExtractionConfig, PlanodomConfig
from planodom.geometry import transform_from_rpy_xyz
from planodom.odometry import run_odometry
from planodom.odometry.seed_extraction import SEED_EPOCHS, seed_extraction
from planodom.scan import Scan


def test_seed_refuses_only_before_the_second_epoch_is_registered():
    seed = ExtractionConfig(ransac_unjudged="seed")
    assert [seed_extraction(seed, k).ransac_unjudged for k in range(4)] == [
        "refused", "refused", "seed", "seed"
    ]  # fmt: skip
    assert seed_extraction(seed, SEED_EPOCHS) is seed
    for mode in ("kept", "refused"):
        cfg = ExtractionConfig(ransac_unjudged=mode)
        assert all(seed_extraction(cfg, k) is cfg for k in range(4))


def test_the_odometry_extracts_its_first_two_epochs_with_refused():
    world = world_planes(np.random.default_rng(5), 10)
    poses = [transform_from_rpy_xyz(0.0, 0.0, 0.03 * k, 0.1 * k, 0.0, 0.0) for k in range(4)]
    planes = [observe(world, T) for T in poses]
    calls: list[tuple[int, str]] = []

    def extractor(scan, cfg, twist=None):
        calls.append((int(scan.points[0, 0]), cfg.ransac_unjudged))
        return planes[int(scan.points[0, 0])]

    scans = [Scan(np.full((1, 3), float(k))) for k in range(4)]
    cfg = PlanodomConfig.from_dict({"extraction": {"ransac_unjudged": "seed"}})
    run_odometry(scans, cfg, extractor=extractor, times=[0.0, 0.1, 0.2, 0.3])
    assert calls == [(0, "refused"), (1, "refused"), (2, "seed"), (3, "seed")]
