"""Every wrong plane tie of the batch with loops, classified against the truth (issue 14).

One lap of a procedural world (as ``planodom experiment loops``: the same odometry and
relative poses), the batch with loop closure (covariances off: they change no pose), and
one line per re-identification that joins two true surfaces not in one plane (two
segments of a wall are one plane): its epoch, the true surfaces joined (the scan plane's
and the landmark's), the angle between them and the offset between them along their
normal (an alias of parallel walls: the spacing), the map match it came from (rank,
verdict, squared Mahalanobis distance from the tracked correction, the verification's
drift sigma per axis since that correction, the predicted and the matched pose's
horizontal distance from the truth), whether the gate after the solve removed it, and
its squared whitened error at the gate's last round against the gate's limit. The first
line (JSON) holds the lap's ATE (xy, rmse), the loop-end error and the counts of
``planodom experiment loops``; then the loop hypotheses (factors, epochs, truth errors,
each factor's chi2 at the gate's last round and the likelihood-ratio increase). A tie of a
rotation-only match also shows its offset residual at the match's pose (``d_old - d_curr``,
:class:`planodom.smoothing.match_fit.OffsetFit`) against its tied wall and against the
nearest other old wall parallel to it: the association ties the nearer.

    uv run python experiments/wrong_ties.py 32 0.02 [JSON_CONFIG_CHANGES] [--odometry FILE]

``--lap-cache DIR``: the default odometry from ``nees_gauge.load``'s cache instead.
``--odometry FILE``: the lap's odometry (a pickle) is read from FILE if it exists (made by
the same world, noise and options but the smoothing's, else an error), else run and
written there: the smoothing's options can then be compared without the odometry's
minutes (a change of the odometry's own options needs a file of its own).
"""

from __future__ import annotations

import json
import pickle
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy.stats import chi2

import planodom.smoothing.batch as batch
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.experiments.loops import coplanar
from planodom.geometry import invert_transform
from planodom.metrics import ate
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.loop_records import (
    gate_reidentifications,
    loop_factor_counts,
    reidentification_counts,
)
from planodom.smoothing.run import smoothing_config, smoothing_relatives


def lap_odometry(index: int, noise: float, cfg: PlanodomConfig, cache: Path | None) -> tuple:
    """(planes, relative poses, true poses (E, 4, 4) from the first) of one lap: the batch's
    odometry (:func:`smoothing_config` of ``cfg``), run or read from ``cache`` (keyed on the
    world, the noise and every option but the smoothing's, which the odometry does not
    read); the relative poses, which read the smoothing's options, computed here."""
    odometry_cfg = smoothing_config(cfg)
    key = {"world": index, "noise_m": noise, **odometry_cfg.model_dump(exclude={"smoothing"})}
    if cache is not None and cache.exists():
        with cache.open("rb") as f:
            stored = pickle.load(f)  # a file this script wrote
        if stored["key"] != key:
            raise SystemExit(f"{cache}: made by another world, noise or odometry option")
        odo, gt = stored["odometry"], stored["gt"]
    else:
        world = world_for(index)
        full = simulate_world(world, noise, n_epochs=None, all_fields=True)
        gt = invert_transform(full.poses[0])[None] @ full.poses
        odo = run_odometry(world_fields(world, full), odometry_cfg)
        if cache is not None:
            with cache.open("wb") as f:
                pickle.dump({"key": key, "odometry": odo, "gt": gt}, f)
    return odo.planes, smoothing_relatives(odo, cfg), gt


def offset_note(m, landmark: int) -> str:
    """A rotation-only match's offset residuals (m) of the tie to ``landmark``: against its
    tied wall and the nearest other parallel old wall ('' for a full match)."""
    rows = [t for t, (j, _) in enumerate(m.ties) if j == landmark]
    if m.offsets is None or not rows:
        return ""
    row, tied = m.offsets.residuals[rows[0]], m.offsets.tied[rows[0]]
    others = [abs(x) for n, x in enumerate(row) if n != tied and np.isfinite(x)]
    nearest = f"{min(others):.2f}" if others else "none"
    return f" | offset residual tied {row[tied]:+.2f} m, nearest other parallel wall {nearest} m"


def main(argv: list[str]) -> None:
    cache = None
    if "--odometry" in argv:
        at = argv.index("--odometry")
        cache, argv = Path(argv[at + 1]), argv[:at] + argv[at + 2 :]
    lap_cache = None
    if "--lap-cache" in argv:  # nees_gauge's cache of the default odometry (DIR)
        at = argv.index("--lap-cache")
        lap_cache, argv = Path(argv[at + 1]), argv[:at] + argv[at + 2 :]
    index, noise = int(argv[0]), float(argv[1])
    changes = json.loads(argv[2]) if len(argv) > 2 else {}
    world = world_for(index)
    cfg = PlanodomConfig().updated(changes)  # the odometry's options too, not only the smoothing's
    if lap_cache is not None:
        sys.path.insert(0, str(Path(__file__).parent))
        import nees_gauge

        _, full, _, odo, relatives = nees_gauge.load(index, noise, lap_cache)
        epoch_planes, gt = odo.planes, invert_transform(full.poses[0])[None] @ full.poses
    else:
        epoch_planes, relatives, gt = lap_odometry(index, noise, cfg, cache)
    chi: dict[int, tuple[float, float]] = {}  # tie factor -> (its chi2, the gate's limit)

    def gate(builder, graph, gaussian, values):  # the gate, its last verdicts noted
        q = builder.config.loop_gate_quantile
        ties = {r.factor for r in builder.reidentifications}
        tracked = [
            2 * f.error(values) for i, f in gaussian.items() if i not in ties and f.dim() == 3
        ]
        limit = max(chi2.ppf(q, 3), float(np.quantile(tracked, q)) if tracked else 0.0)
        for r in builder.reidentifications:
            if not r.removed:
                chi[r.factor] = (
                    2 * gaussian.get(r.factor, graph.at(r.factor)).error(values),
                    limit,
                )
        return gate_reidentifications(builder, graph, gaussian, values)

    batch.gate_reidentifications = gate  # this process only: the batch's gate, observed
    run_cfg = cfg.updated(
        {"smoothing.loop_closure": True, "smoothing.compute_covariances": False, **changes}
    )
    res = batch.smooth_batch(epoch_planes, relatives, run_cfg)
    same = coplanar(world.scene)
    head = {
        "world": index, "noise_m": noise, "changes": changes,
        "ate_m": ate(res.poses, gt, xy_only=True)["rmse"],
        "loop_end_m": float(np.linalg.norm(res.poses[-1][:2, 3] - gt[-1][:2, 3])),
        **reidentification_counts(res.reidentifications, same),
        **loop_factor_counts(res.loop_factors, gt),
    }  # fmt: skip
    print(json.dumps(head))
    planes = {s.id: np.append(s.normal, s.offset) for s in world.scene.surfaces}
    matches = {m.epoch: m for m in res.loop_matches}
    for r in res.reidentifications:
        if min(r.truth_plane, r.truth_landmark) < 0 or same(r.truth_plane, r.truth_landmark):
            continue
        a, b = planes[r.truth_plane], planes[r.truth_landmark]
        b = b if a[:3] @ b[:3] >= 0 else -b
        m, k = matches[r.epoch], r.epoch
        placed = m.T_world_pred @ m.T_pred_curr
        sd = float(np.sqrt(m.drift[1, 1])) if m.drift.any() else float("nan")
        c2, limit = chi.get(r.factor, (float("nan"), float("nan")))
        print(
            f"epoch {k} surfaces {r.truth_plane}->{r.truth_landmark} "
            f"angle {np.degrees(np.arccos(np.clip(a[:3] @ b[:3], -1, 1))):.1f} deg "
            f"offset {b[3] - a[3]:+.2f} m | match {'full' if m.full else 'rotation'} "
            f"{m.verdict} mahalanobis {m.mahalanobis:.2f} drift sd {sd:.2f} m "
            f"predicted {np.linalg.norm(m.T_world_pred[:2, 3] - gt[k][:2, 3]):.2f} m "
            f"matched {np.linalg.norm(placed[:2, 3] - gt[k][:2, 3]):.2f} m off | "
            f"{'removed' if r.removed else 'kept'} chi2 {c2:.1f} (limit {limit:.3g})"
            + offset_note(m, r.landmark)
        )
    groups = defaultdict(list)
    for f in res.loop_factors:
        groups[f.group].append(f)
    for g, fs in sorted(groups.items()):
        err = [float(np.linalg.norm(f.truth_error(gt)[3:])) for f in fs]
        print(
            f"hypothesis {g}: {len(fs)} factors, epochs {fs[0].epoch}-{fs[-1].epoch} against "
            f"{sorted({f.old for f in fs})}, {min(err):.2f}-{max(err):.2f} m off the truth, "
            f"{sum(f.removed for f in fs)} removed; chi2 {[round(f.chi2, 1) for f in fs]} "
            f"(limit {chi2.ppf(run_cfg.smoothing.loop_gate_quantile, 5):.1f}), "
            f"increase {fs[0].increase:.3g}"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
