"""How well can an epoch's angular rate be predicted from the rates measured before it?

The 2D rig's streaming odometry deskews an epoch with the angular rate of the last step
(constant twist) and extracts it again with the epoch's own (``odometry.deskew_iterations``)
when the two differ by more than ``deskew_rate_tolerance_deg_s``; almost every refinement
is for the rate (docs/RESULTS.md, RIG2DPASS). This script scores generic online predictors
of the next epoch's rate from the previous epochs' rates, with no model of the
simulator's motion (no sinusoid, no frequency): each predictor sees only the sequence.

Targets, from the ground truth of the world (``T_world_base`` at the epoch times t_k;
s_k the mean rate over [t_{k-1}, t_k]): ``epoch``: (s_k + s_{k+1}) / 2, the rate about the
epoch's time, which the odometry's own twist of a step (with its deskewing offset)
measures (median error 0.22 deg/s against 0.54 for s_k on worlds 0-18 at 6 mm);
``sweep``: s_{k+1}, the mean over the epoch's points' interval [t_k, t_{k+1}], what an
ideal deskewing would use; ``own``: the own twist the odometry measured at epoch k (the
refinement's trigger, ``odometry.deskew_rate_tolerance_deg_s``).

``--source truth``: the previous rates are the true epoch rates plus Gaussian noise of
``--sigma`` deg/s per component (the velocity's 0.01 m/s per deg/s). ``--source
odometry``: they are the own twists of a default streaming run (kept in ``--cache``), each
predictor fed the contiguous run of rates measured before the epoch. Epochs after the
first ``--skip`` are scored, each after a measured one.

    uv run python experiments/rate_prediction.py --source truth --worlds 0 2 ... 18
    uv run python experiments/rate_prediction.py --source odometry --worlds 0 2 ... 18
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
from collections.abc import Callable  # noqa: E402

import numpy as np  # noqa: E402

from planodom.experiments.generalisation import world_for  # noqa: E402
from planodom.odometry.trend import trend_twist  # noqa: E402
from planodom.se3 import se3_log  # noqa: E402

#: ``predictor(history (H, D), oldest first) -> (D,)`` the next value.
Predictor = Callable[[np.ndarray], np.ndarray]


def _ar(h: np.ndarray, order: int, window: int) -> np.ndarray:
    """Autoregression of ``order`` with an intercept fitted by least squares, per component,
    on the last ``window`` values; constant until it has twice as many equations as terms.
    Its one-step prediction is clipped to the window's range widened by its spread (an
    online fit of a handful of noisy points can be explosive)."""
    h = h[-window:]
    n = len(h) - order
    if n < 2 * (order + 1):
        return h[-1].copy()
    out = np.empty(h.shape[1])
    for j in range(h.shape[1]):
        x = h[:, j]
        A = np.column_stack(
            [np.ones(n)] + [x[order - i - 1 : len(x) - i - 1] for i in range(order)]
        )
        coef = np.linalg.lstsq(A, x[order:], rcond=None)[0]
        out[j] = coef[0] + coef[1:] @ x[::-1][:order]
        lo, hi, span = x.min(), x.max(), x.max() - x.min()
        out[j] = np.clip(out[j], lo - span, hi + span)
    return out


def _ari(h: np.ndarray, order: int, window: int) -> np.ndarray:
    """Autoregression of ``order`` on the changes (no intercept: ARI(order, 1)), fitted on
    the last ``window`` values: the last value plus the predicted change. A lasting
    change of level (a turn) is kept, not pulled back to the window's mean."""
    d = np.diff(h[-window:], axis=0)
    if len(d) - order < 2 * order:
        return h[-1].copy()
    return h[-1] + _ar_fit(d, order, intercept=False)


def _ar_fit(x: np.ndarray, order: int, intercept: bool) -> np.ndarray:
    """(D,) the next row of ``x`` (H, D) by a least-squares autoregression per column."""
    n = len(x) - order
    out = np.empty(x.shape[1])
    for j in range(x.shape[1]):
        c = x[:, j]
        lags = [c[order - i - 1 : len(c) - i - 1] for i in range(order)]
        A = np.column_stack(([np.ones(n)] if intercept else []) + lags)
        coef = np.linalg.lstsq(A, c[order:], rcond=None)[0]
        out[j] = (coef[0] if intercept else 0.0) + coef[int(intercept) :] @ c[::-1][:order]
    return out


def _selected(h: np.ndarray, order: int, window: int, recent: int) -> np.ndarray:
    """The autoregression's prediction (:func:`_ar`) where it predicted the last ``recent``
    values of ``h`` better than the constant one did (summed squared error, all
    components), else the last value: an online choice between the two forecasts."""
    if len(h) < 3 * order + 2 + recent:
        return h[-1].copy()
    err_ar = err_c = 0.0
    for i in range(len(h) - recent, len(h)):
        err_ar += float(np.sum((_ar(h[:i], order, window) - h[i]) ** 2))
        err_c += float(np.sum((h[i - 1] - h[i]) ** 2))
    return _ar(h, order, window) if err_ar < err_c else h[-1].copy()


def _damped(h: np.ndarray, window: int) -> np.ndarray:
    """Damped trend: the last value plus phi times the last change, phi (in [0, 1]) the
    least-squares lag-one regression of the changes over the last ``window`` values."""
    d = np.diff(h[-window:], axis=0)
    if len(d) < 3:
        return h[-1].copy()
    num = np.sum(d[1:] * d[:-1], axis=0)
    den = np.maximum(np.sum(d[:-1] ** 2, axis=0), 1e-300)
    return h[-1] + np.clip(num / den, 0.0, 1.0) * d[-1]


def _trend(h: np.ndarray, window: int) -> np.ndarray:
    """The project's trend with shrinkage (:func:`planodom.odometry.trend.trend_twist`)."""
    return trend_twist(h[-window:]) if len(h) >= max(window, 4) else h[-1].copy()


PREDICTORS: dict[str, Predictor] = {
    "constant": lambda h: h[-1].copy(),
    "linear": lambda h: 2 * h[-1] - h[-2] if len(h) >= 2 else h[-1].copy(),
    "half-linear": lambda h: 1.5 * h[-1] - 0.5 * h[-2] if len(h) >= 2 else h[-1].copy(),
    "mean3": lambda h: h[-3:].mean(axis=0),
    "trend4": lambda h: _trend(h, 4),
    "trend6": lambda h: _trend(h, 6),
    "trend8": lambda h: _trend(h, 8),
    "damped10": lambda h: _damped(h, 10),
    "damped20": lambda h: _damped(h, 20),
    "ar1-10": lambda h: _ar(h, 1, 10),
    "ar1-20": lambda h: _ar(h, 1, 20),
    "ar2-12": lambda h: _ar(h, 2, 12),
    "ar2-20": lambda h: _ar(h, 2, 20),
    "ar2-40": lambda h: _ar(h, 2, 40),
    "ar2-60": lambda h: _ar(h, 2, 60),
    "ar3-40": lambda h: _ar(h, 3, 40),
    "ar4-40": lambda h: _ar(h, 4, 40),
    "ar4-60": lambda h: _ar(h, 4, 60),
    "ar6-60": lambda h: _ar(h, 6, 60),
    "sel4-60-10": lambda h: _selected(h, 4, 60, 10),
    "sel4-60-20": lambda h: _selected(h, 4, 60, 20),
    "ari2-40": lambda h: _ari(h, 2, 40),
    "ari3-60": lambda h: _ari(h, 3, 60),
    "ari4-60": lambda h: _ari(h, 4, 60),
}


def true_steps(world_index: int, epochs: int) -> tuple[np.ndarray, float]:
    """(epochs, 6) true step twists (rad/s, m/s; row k the mean over [t_{k-1}, t_k], row 0
    zero) of world ``world_index`` at its epoch rate, one more row for [t_E-1, t_E]; and dt."""
    world = world_for(world_index)
    dt = 1.0 / world.epoch_rate
    T = world.trajectory.poses(np.arange(epochs + 1) * dt)
    steps = np.zeros((epochs + 1, 6))
    for k in range(1, epochs + 1):
        steps[k] = se3_log(np.linalg.inv(T[k - 1]) @ T[k]) / dt
    return steps, dt


def odometry_rates(world_index: int, noise: float, epochs: int) -> tuple[np.ndarray, np.ndarray]:
    """The own twists (epochs, 6) of a default streaming run of world ``world_index`` at
    range noise ``noise`` (m; row k the step k's, NaN where unresolved or k = 0) and
    whether each was measured (status not unresolved)."""
    import planodom.odometry.odometry as odo_mod
    from planodom.config import PlanodomConfig
    from planodom.experiments.generalisation import declared_sweep
    from planodom.odometry import run_odometry
    from planodom.odometry.relative import Status
    from planodom.simulation.random_world import simulate_world, world_fields

    own = np.full((epochs, 6), np.nan)
    first: list[int] = []
    real = odo_mod.PlaneOdometry._commit

    def commit(self, epoch, best, t):
        first.append(id(self)) if not first else None
        if id(self) == first[0] and self.times and best.relative.status is not Status.UNRESOLVED:
            own[epoch.index] = best.own_twist(t - self.times[-1])
        return real(self, epoch, best, t)

    odo_mod.PlaneOdometry._commit = commit  # type: ignore[method-assign]
    try:
        world = world_for(world_index)
        sim = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
        run_odometry(world_fields(world, sim), declared_sweep(world, PlanodomConfig()))
    finally:
        odo_mod.PlaneOdometry._commit = real  # type: ignore[method-assign]
    return own, np.isfinite(own[:, 0])


def _cached(folder: str | None, w: int, noise: float, epochs: int) -> np.ndarray:
    """:func:`odometry_rates` of world ``w``, kept in (and read from) ``folder``."""
    path = None if folder is None else os.path.join(folder, f"own_{w}_{noise:g}_{epochs}.npy")
    if path is not None and os.path.exists(path):
        return np.load(path)
    own = odometry_rates(w, noise, epochs)[0]
    if path is not None:
        os.makedirs(folder, exist_ok=True)  # type: ignore[arg-type]
        np.save(path, own)
    return own


def score(
    measured: np.ndarray, truth: np.ndarray, skip: int, part: slice
) -> dict[str, dict[str, np.ndarray]]:
    """Per predictor, per target, the error norms (deg/s for the rate, m/s for the
    velocity: ``part``) of its predictions for epochs ``skip`` .. E-1. ``measured`` (E, 6)
    NaN where not measured (left out of the history); ``truth`` (E+1, 6) true steps.
    Targets: ``epoch`` (truth[k] + truth[k+1]) / 2, ``sweep`` truth[k+1], ``own``
    measured[k] (where measured). Only epochs after a measured one are scored; the
    history is the contiguous run of measured steps before (an even sampling)."""
    scale = np.degrees(1.0) if part == slice(0, 3) else 1.0
    out: dict[str, dict[str, list[float]]] = {n: {"epoch": [], "sweep": [], "own": []}
                                              for n in PREDICTORS}  # fmt: skip
    ok = np.isfinite(measured[:, 0])
    for k in range(skip, len(measured)):
        if not ok[k - 1]:  # after an unresolved epoch the odometry deskews with no twist
            continue
        start = k - 1
        while start > 1 and ok[start - 1]:
            start -= 1
        h = measured[start:k][:, part]  # the contiguous run of measured steps before k
        for name, pred in PREDICTORS.items():
            p1 = pred(h)
            e = out[name]
            epoch = 0.5 * (truth[k, part] + truth[k + 1, part])
            e["epoch"].append(scale * float(np.linalg.norm(p1 - epoch)))
            e["sweep"].append(scale * float(np.linalg.norm(p1 - truth[k + 1, part])))
            own = scale * float(np.linalg.norm(p1 - measured[k, part])) if ok[k] else np.nan
            e["own"].append(own)
    return {n: {t: np.array(v) for t, v in d.items()} for n, d in out.items()}


def _table(scores: list[dict[str, dict[str, np.ndarray]]], title: str, tol: float) -> None:
    """Print median, 90th percentile and share within ``tol`` of each predictor's errors
    pooled over ``scores`` (one per world)."""
    print(f"--- {title}")
    print(
        f"  {'predictor':12s} "
        + "  ".join(f"{t + ' med/p90/<tol':>22s}" for t in ("epoch", "sweep", "own"))
    )
    base = None
    for name in PREDICTORS:
        cells = []
        for t in ("epoch", "sweep", "own"):
            e = np.concatenate([s[name][t] for s in scores])
            e = e[np.isfinite(e)]
            med = float(np.median(e))
            if name == "constant":
                base = base or {}
                base[t] = med
            rel = med / base[t] if base else 1.0
            cells.append(
                f"{med:6.3f} ({rel:4.2f}) {np.percentile(e, 90):6.3f} {np.mean(e < tol):4.2f}"
            )
        print(f"  {name:12s} " + "  ".join(f"{c:>22s}" for c in cells))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[0, 2, 4])
    ap.add_argument("--source", choices=("truth", "odometry"), default="truth")
    ap.add_argument("--sigma", type=float, nargs="+", default=[0.0, 0.16, 0.39])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--skip", type=int, default=10)
    ap.add_argument("--cache", help="folder keeping the odometry's own twists (npz)")
    ap.add_argument("--predictors", nargs="+", help="only these (and constant)")
    ap.add_argument("--per-world", action="store_true", help="each world's medians too")
    args = ap.parse_args()
    if args.predictors:
        for name in [n for n in PREDICTORS if n != "constant" and n not in args.predictors]:
            del PREDICTORS[name]
    rng = np.random.default_rng(0)
    truths = {w: true_steps(w, args.epochs) for w in args.worlds}
    levels = args.sigma if args.source == "truth" else args.noise
    for level in levels:
        rates, speeds = [], []
        for w, (truth, _) in truths.items():
            if args.source == "truth":
                sigma = np.r_[np.radians(level) * np.ones(3), 0.01 * level * np.ones(3)]
                noise = sigma * rng.standard_normal((args.epochs, 6))
                measured = np.full((args.epochs, 6), np.nan)
                measured[1:] = 0.5 * (truth[1:-1] + truth[2:]) + noise[1:]  # the epoch's rate
                measured[0] = np.nan
            else:
                measured = _cached(args.cache, w, level, args.epochs)
            rates.append(score(measured, truth, args.skip, slice(0, 3)))
            if args.per_world:
                cells = [f"{n} {np.nanmedian(d['epoch']):.2f}/{np.nanmedian(d['own']):.2f}"
                         for n, d in rates[-1].items()]  # fmt: skip
                print(f"  world {w} epoch/own median deg/s: " + ", ".join(cells))
            speeds.append(score(measured, truth, args.skip, slice(3, 6)))
        tag = f"sigma {level} deg/s" if args.source == "truth" else f"noise {level * 1e3:g} mm"
        _table(rates, f"{tag}: angular rate, deg/s (median (x constant's), p90, share < 0.5)", 0.5)
        _table(speeds, f"{tag}: velocity, m/s (median (x constant's), p90, share < 0.5)", 0.5)


if __name__ == "__main__":
    main()
