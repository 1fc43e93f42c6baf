"""The fixed-lag smoother's marginal covariances, against the batch marginals."""

from __future__ import annotations

import numpy as np

from planodom.config import SmoothingConfig
from planodom.smoothing import smooth_batch, smooth_windowed
from planodom.smoothing.synthetic import make_sequence

# Without the deskew noise: batch estimates it from the whole run, the fixed-lag smoother
# from the epochs so far (smoothing.deskew_noise), and these tests compare the two.
GAUSSIAN = SmoothingConfig(
    robust_kernel="none", covariances_relative_to_first=False, deskew_noise="none"
)


def replace(config: SmoothingConfig, **changes: object) -> SmoothingConfig:
    return config.model_copy(update=changes)


NOISE = dict(sigma_rotation=1e-3, sigma_translation=0.01, sigma_normal=0.005, sigma_offset=0.01)


def test_window_covering_the_sequence_gives_the_batch_marginals() -> None:
    seq = make_sequence(15, seed=4, **NOISE)
    config = replace(GAUSSIAN, window=20, relinearize_threshold=1e-4)
    batch = smooth_batch(seq.planes, seq.relatives, config)
    windowed = smooth_windowed(seq.planes, seq.relatives, config)
    assert batch.covariances is not None and windowed.covariances is not None
    assert windowed.covariances.shape == (15, 6, 6)
    sigma_b = np.sqrt(np.diagonal(batch.covariances, axis1=1, axis2=2))
    sigma_w = np.sqrt(np.diagonal(windowed.covariances, axis1=1, axis2=2))
    np.testing.assert_allclose(sigma_w, sigma_b, rtol=1e-3)


def test_short_window_marginals_are_no_smaller_than_the_batch() -> None:
    """A pose's marginal when it leaves the window lacks the later measurements: no smaller
    than the batch's (up to linearisation points); the newest pose's is the batch's (in a
    linear Gaussian problem marginalisation is exact)."""
    seq = make_sequence(30, seed=6, **NOISE)
    config = replace(GAUSSIAN, window=5, delta_max=3)
    batch = smooth_batch(seq.planes, seq.relatives, config)
    windowed = smooth_windowed(seq.planes, seq.relatives, config)
    assert windowed.covariances is not None and batch.covariances is not None
    assert np.all(np.isfinite(windowed.covariances))
    assert np.all(np.linalg.eigvalsh(windowed.covariances) > 0)
    var_w = np.diagonal(windowed.covariances, axis1=1, axis2=2)
    var_b = np.diagonal(batch.covariances, axis1=1, axis2=2)
    assert np.all(var_w >= 0.99 * var_b)
    np.testing.assert_allclose(var_w[-1], var_b[-1], rtol=0.01)
    assert var_w[10].sum() > 1.05 * var_b[10].sum()
    # without the option, or with the batch backend (no marginals in gtsam): none
    off = smooth_windowed(seq.planes, seq.relatives, replace(config, compute_covariances=False))
    batch_backend = replace(config, windowed_backend="batch")
    assert off.covariances is None
    assert smooth_windowed(seq.planes, seq.relatives, batch_backend).covariances is None


def test_the_qr_fallback_continues_from_the_smoothers_state() -> None:
    """Cholesky ("auto") gives QR's estimate; rebuilding the smoother with QR mid-run (what
    "auto" does when Cholesky finds the system indeterminant) continues where it was: the
    errors of a QR-only run (up to the relinearisation of every factor at the rebuild)."""
    from planodom.smoothing.batch import group_by_epoch
    from planodom.smoothing.windowed import WindowedSmoother

    seq = make_sequence(30, seed=6, **NOISE)
    config = replace(GAUSSIAN, window=5, delta_max=3)
    by_epoch = group_by_epoch(seq.relatives, 30)
    runs = [WindowedSmoother(replace(config, windowed_factorization=f)) for f in ("QR", "auto")]
    rebuilt = WindowedSmoother(replace(config, windowed_factorization="auto"))
    assert rebuilt.factorization == "CHOLESKY"
    for k, planes in enumerate(seq.planes):
        for smoother in [*runs, rebuilt]:
            smoother.add_epoch(planes, by_epoch[k])
        if k == 12:
            rebuilt._fall_back_to_qr()
    assert rebuilt.factorization == "QR" and rebuilt.qr_fallbacks == 1
    qr, cholesky, after = (s.result() for s in [*runs, rebuilt])
    assert after.qr_fallback_epochs == [12] and qr.qr_fallback_epochs == []
    np.testing.assert_allclose(cholesky.poses, qr.poses, atol=1e-9)
    error = [np.abs(r.poses[:, :3, 3] - seq.poses[:, :3, 3]).max() for r in (qr, after)]
    assert error[1] < 1.1 * error[0]
    np.testing.assert_allclose(after.poses[:, :3, 3], qr.poses[:, :3, 3], atol=0.01)
    assert after.covariances is not None and qr.covariances is not None
    sigma = [np.sqrt(np.diagonal(r.covariances, axis1=1, axis2=2)) for r in (after, qr)]
    np.testing.assert_allclose(sigma[0], sigma[1], rtol=0.05)
