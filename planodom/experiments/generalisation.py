"""Unseen worlds (issue 11): planodom against the oracle and the point-based peers.

For each random world (:func:`planodom.simulation.random_world.random_world`; world ``i``
has seed ``i`` and, so that both kinds of rig are covered, a 2D rig for even ``i`` and a
16 / 32 / 64-beam lidar in turn for odd ``i``) and each range noise, one run is simulated
(continuous motion, the world's fields) and given to every method:

- ``planodom``: the configuration as given (by default ``odometry.pipeline: auto``, what a
  user gets: the plane-map odometry for lidars, the paper's "wocsc" for the 2D rig);
  on a lidar world the lidar's sweep convention (counter-clockwise, first column at
  -180 deg, one turn per ``1 / rate_hz``, epochs stamped at the sweep start) is declared
  in ``extraction.sweep`` as a user declares their sensor (:func:`declared_sweep`), so
  that clouds stored without times are deskewed with times from the azimuth (unless the
  configuration given declares a convention itself);
  ``planodom-wocsc``: the paper's pipeline forced on every rig; on request
  ``planodom-sda-mean`` (the paper's other pipeline) and ``planodom-offline`` (the
  configuration given with two deskewing passes along the poses of the epochs on both
  sides, ``odometry.deskew_passes``: what a run over a recording can reach offline);
- ``oracle`` (:mod:`planodom.oracle`: true planes, known associations, true deskewing);
- ``kiss-icp`` (when installed: ``uv sync --extra baselines``) and ``open3d-icp``.

Per method: per-epoch rotation and xy error rms over all epochs after the first (bridged
ones included: what a user gets), ATE (xy, origin-aligned), unresolved and degenerate
epochs, the longest run of epochs without a measurement (unresolved) and of those where
the oracle measures, and epochs/s (after an untimed warm-up run of every method on the
first epochs of worlds 0 and 1, so that no method's first world pays the process's imports).
Outputs: ``runs.csv`` (one row per world, noise and method), ``summary.md/csv`` (per
noise, rig class and method: median and worst over the worlds of the ratios to the
oracle), ``worst_world.png`` (top view of the world where planodom's ATE is the largest
multiple of the oracle's) and ``config.yaml``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.peers import kiss_available, kiss_icp_poses, open3d_icp_poses
from planodom.experiments.plots import plot_panels
from planodom.experiments.tables import ExperimentResult, Rows, write_tables
from planodom.geometry import invert_transform
from planodom.metrics import ate, per_epoch_errors, relative_motions
from planodom.odometry import run_odometry
from planodom.oracle import run_oracle
from planodom.simulation.random_world import World, random_world, simulate_world, world_fields
from planodom.simulation.sensors import SpinningLidar

NOISE_LEVELS = (0.0, 0.006, 0.02, 0.1)
#: planodom's methods: name -> overrides of the configuration given (none: as given).
PLANODOM_METHODS: dict[str, dict[str, object]] = {
    "planodom": {},
    "planodom-wocsc": {"odometry.pipeline": "wocsc"},
    "planodom-sda-mean": {"odometry.pipeline": "sda-mean"},
    # offline: the streaming pass, then two passes deskewed along the curve through the
    # poses of the epochs on both sides (odometry.deskew_passes; off in the default
    # configuration because it costs 3-4x the time and is mixed on the 2D rig)
    "planodom-offline": {"odometry.deskew_passes": 2},
}
METHODS = (*PLANODOM_METHODS, "oracle", "kiss-icp", "open3d-icp")
LIDARS = ("lidar16", "lidar32", "lidar64")
COLOURS = {"planodom": "magenta", "planodom-wocsc": "tab:green", "planodom-sda-mean": "tab:olive",
           "planodom-offline": "tab:purple",
           "oracle": "black", "kiss-icp": "tab:orange", "open3d-icp": "tab:red"}  # fmt: skip
DEFAULT_METHODS = ("planodom", "planodom-wocsc", "oracle", "kiss-icp", "open3d-icp")


@dataclass
class MethodRun:
    """One method on one world at one noise level.

    Attributes:
        world: the world's seed. kind, family: "outdoor" | "indoor", "rig2d" | "lidarNN".
        noise: m. method: name. poses: (E, 4, 4) from identity. statuses: per epoch
        ("first", "ok", "degenerate", "unresolved"), None for a peer (no status).
        seconds: wall time of the method (extraction and odometry for planodom).
        gt_poses: (E, 4, 4) truth from identity. n_planes: (E,) planes per epoch, or None.
    """

    world: int
    kind: str
    family: str
    noise: float
    method: str
    poses: np.ndarray
    statuses: list[str] | None
    seconds: float
    gt_poses: np.ndarray
    n_planes: np.ndarray | None = None
    metrics: dict[str, float] = field(default_factory=dict)


GeneralisationExperiment = ExperimentResult[MethodRun]


def world_for(index: int, motion: str = "vehicle") -> World:
    """World ``index`` of the experiment: seed ``index``, a 2D rig for even indices and
    the lidars in turn for odd ones; with ``motion`` "handheld" the hand-held world of seed
    ``index`` (a lidar drawn from the seed, :func:`random_world`) for every index."""
    if motion == "handheld":
        return random_world(index, motion="handheld")
    family = "rig2d" if index % 2 == 0 else LIDARS[(index // 2) % len(LIDARS)]
    return random_world(index, rig=family)


def rig_class(index: int, motion: str = "vehicle") -> str:
    """ "rig2d" or "lidar": the rig class of world ``index`` (:func:`world_for`)."""
    return "rig2d" if index % 2 == 0 and motion != "handheld" else "lidar"


def declared_sweep(world: World, config: PlanodomConfig) -> PlanodomConfig:
    """``config`` with the sweep convention of ``world``'s lidar declared
    (``extraction.sweep``, :class:`planodom.simulation.sensors.SpinningLidar`: counter-
    clockwise, column 0 at -180 deg, sweeps starting at the epoch times); unchanged for a
    2D rig or when ``config`` declares one already."""
    lidars = [s for s in world.sensor_rig.sensors if isinstance(s, SpinningLidar)]
    if len(lidars) != 1 or config.extraction.sweep.rotation != "none":
        return config
    lidar = lidars[0]
    sweep = {"rotation": "ccw", "start_azimuth_deg": float(np.degrees(lidar.azimuths[0])),
             "period_s": 1.0 / lidar.rate_hz, "start_time_s": lidar.time_offset}  # fmt: skip
    return config.updated({"extraction.sweep": sweep}, source="generalisation")


def longest_run(mask: np.ndarray) -> int:
    """Length of the longest run of True in ``mask`` (E,) bool."""
    best = cur = 0
    for v in np.asarray(mask, dtype=bool):
        cur = cur + 1 if v else 0
        best = max(best, cur)
    return best


def _metrics(mr: MethodRun, oracle_statuses: list[str] | None) -> dict[str, float]:
    """Errors, counts and speed of one run (module docstring)."""
    err = per_epoch_errors(relative_motions(mr.poses), relative_motions(mr.gt_poses))
    rot = np.degrees(np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2))
    xy = np.hypot(err["x"], err["y"])
    n = len(mr.poses)
    out = {
        "rot_rms_deg": float(np.sqrt(np.mean(rot**2))),
        "xy_rms_m": float(np.sqrt(np.mean(xy**2))),
        "ate_xy_m": ate(mr.poses, mr.gt_poses, align="origin", xy_only=True)["rmse"],
        "epochs_per_s": n / mr.seconds if mr.seconds > 0 else float("nan"),
    }
    if mr.statuses is None:
        return out | {k: float("nan") for k in ("unresolved", "degenerate", "gap", "gap_oracle")}
    st = np.array(mr.statuses)
    gap = st == "unresolved"
    oracle_measures = (
        np.array(oracle_statuses) != "unresolved" if oracle_statuses else np.ones(n, bool)
    )
    return out | {
        "unresolved": float(gap.sum()),
        "degenerate": float((st == "degenerate").sum()),
        "gap": float(longest_run(gap)),
        "gap_oracle": float(longest_run(gap & oracle_measures)),
    }


def run_world(
    world: World,
    noise: float,
    n_epochs: int | None,
    config: PlanodomConfig,
    methods: Sequence[str],
    say: Callable[[str], None],
) -> list[MethodRun]:
    """Every method in ``methods`` on one simulated run of ``world`` at ``noise`` (m)."""
    full = simulate_world(world, noise, n_epochs=n_epochs, all_fields=True)
    run = world_fields(world, full)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    fam, base = world.description["family"], (world.seed, world.kind)
    runs = []

    def add(method, poses, statuses, seconds, n_planes=None):
        runs.append(MethodRun(base[0], base[1], fam, noise, method, poses, statuses, seconds,
                              gt, n_planes))  # fmt: skip

    if "oracle" in methods:
        c0 = time.perf_counter()
        orc = run_oracle(full.scans, full.times, world.trajectory, world.scene)
        add("oracle", orc.poses, orc.statuses, time.perf_counter() - c0, orc.n_planes)
    for method, overrides in PLANODOM_METHODS.items():
        if method in methods:
            say(f"world {world.seed} ({world.kind}, {fam}) sigma {noise * 1000:g} mm: {method}")
            cfg = declared_sweep(world, config)
            if overrides:
                cfg = cfg.updated(overrides, source="generalisation")
            odo = run_odometry(run, cfg)
            add(method, odo.poses, odo.statuses, sum(odo.seconds.values()), odo.n_planes)
    period = 1.0 / world.epoch_rate
    if "kiss-icp" in methods and kiss_available():
        max_range = max(s.max_range for s in world.sensor_rig.sensors)
        add("kiss-icp", *_peer(kiss_icp_poses(run.scans, period, max_range)))
    if "open3d-icp" in methods:
        add("open3d-icp", *_peer(open3d_icp_poses(run.scans)))
    oracle = next((r.statuses for r in runs if r.method == "oracle"), None)
    for r in runs:
        r.metrics = _metrics(r, oracle)
    return runs


def _peer(result: tuple[np.ndarray, float]) -> tuple[np.ndarray, None, float]:
    return result[0], None, result[1]


def _warm_up(world: World, config: PlanodomConfig, methods: Sequence[str]) -> None:
    """Run every method once on a few epochs, untimed: the one-off costs of a process
    (imports, loading the compiled numba kernels from their cache: 2-3 s, the time of
    20-50 lidar epochs) would otherwise be charged to the first world's epochs/s."""
    run_world(world, 0.0, 3, config, [m for m in methods if m != "oracle"], lambda msg: None)


def run_rows(runs: Sequence[MethodRun]) -> list[dict[str, object]]:
    """One row per world, noise and method."""
    return [
        {
            "world": r.world,
            "kind": r.kind,
            "family": r.family,
            "noise_m": r.noise,
            "method": r.method,
            "epochs": len(r.poses),
            **r.metrics,
        }  # fmt: skip
        for r in runs
    ]


def _peer_of(runs: Sequence[MethodRun], method: str, r: MethodRun) -> MethodRun | None:
    """The run of ``method`` on the same world and noise as ``r``."""
    same = (o for o in runs if o.method == method and (o.world, o.noise) == (r.world, r.noise))
    return next(same, None)


def _ratio(runs: Sequence[MethodRun], key: str, r: MethodRun) -> float:
    ref = _peer_of(runs, "oracle", r)
    if ref is None or not ref.metrics[key] > 0:
        return float("nan")
    return r.metrics[key] / ref.metrics[key]


def _speed_vs_kiss(runs: Sequence[MethodRun], r: MethodRun) -> float:
    kiss = _peer_of(runs, "kiss-icp", r)
    return r.metrics["epochs_per_s"] / kiss.metrics["epochs_per_s"] if kiss else float("nan")


def summary_rows(runs: Sequence[MethodRun]) -> list[dict[str, object]]:
    """Per noise, rig class ("rig2d" | "lidar") and method: median and worst over worlds
    of the rotation / xy rms and ATE as ratios to the oracle's (absolute medians too),
    total unresolved, longest gap where the oracle measures, median epochs/s and its ratio
    to KISS-ICP's on the same worlds."""
    rows = []
    groups = sorted({(r.noise, "rig2d" if r.family == "rig2d" else "lidar") for r in runs})
    methods = list(dict.fromkeys(r.method for r in runs))
    for noise, cls in groups:
        for method in methods:
            here = [r for r in runs if r.noise == noise and r.method == method
                    and (r.family == "rig2d") == (cls == "rig2d")]  # fmt: skip
            if not here:
                continue
            row: dict[str, object] = {"noise_m": noise, "rig": cls, "method": method,
                                      "worlds": len(here)}  # fmt: skip
            for key, short in (("rot_rms_deg", "rot"), ("xy_rms_m", "xy"), ("ate_xy_m", "ate")):
                ratios = [_ratio(runs, key, r) for r in here]
                row[f"{key}_median"] = float(np.median([r.metrics[key] for r in here]))
                row[f"{short}_x_oracle_median"] = _finite(np.median, ratios)
                row[f"{short}_x_oracle_worst"] = _finite(np.max, ratios)
            metric = {k: [r.metrics[k] for r in here] for k in here[0].metrics}
            row["unresolved"] = _finite(np.sum, metric["unresolved"])
            row["gap_oracle_worst"] = _finite(np.max, metric["gap_oracle"])
            row["epochs_per_s_median"] = _finite(np.median, metric["epochs_per_s"])
            row["speed_x_kiss_median"] = _finite(np.median, [_speed_vs_kiss(runs, r) for r in here])
            rows.append(row)
    return rows


#: The summary's error columns: metric key, short name, scale to the printed unit.
_SUMMARY_ERRORS = (("rot_rms_deg", "rot", 1.0), ("xy_rms_m", "xy", 100.0), ("ate_xy_m", "ate", 1.0))


def summary_markdown(rows: Rows) -> str:
    """The summary as a compact Markdown table: ratios to the oracle as "median / worst"."""
    head = ["sigma mm", "rig", "method", "n", "rot rms deg (x oracle)", "xy rms cm (x oracle)",
            "ATE m (x oracle)", "unres.", "gap*", "epochs/s (x KISS)"]  # fmt: skip
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def f(v: object, fmt: str = ".3g") -> str:
        return "-" if not isinstance(v, float) or not np.isfinite(v) else format(v, fmt)

    for r in rows:
        cells = [f(1000 * float(r["noise_m"]), "g"), r["rig"], r["method"], r["worlds"]]
        for key, short, scale in _SUMMARY_ERRORS:
            value = f(scale * float(r[f"{key}_median"]))
            med, worst = f(r[f"{short}_x_oracle_median"]), f(r[f"{short}_x_oracle_worst"])
            cells.append(f"{value} ({med} / {worst})")
        cells += [f(r["unresolved"], "g"), f(r["gap_oracle_worst"], "g"),
                  f"{f(r['epochs_per_s_median'])} ({f(r['speed_x_kiss_median'])})"]  # fmt: skip
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    note = ("\nMedians over the worlds; in brackets the ratio to the oracle's on the same "
            "world, median / worst. gap*: longest run of unresolved epochs where the oracle "
            "measures (worst world). ATE: xy, origin-aligned.\n")  # fmt: skip
    return "\n".join(lines) + "\n" + note


def _finite(reduce: Callable, values: Sequence[float]) -> float:
    """``reduce`` over the finite ``values``; NaN when there are none."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(reduce(v)) if len(v) else float("nan")


def plot_worst(runs: Sequence[MethodRun], path: Path) -> tuple[int, float] | None:
    """Top view of the (world, noise) where planodom's ATE is the largest multiple of the
    oracle's: truth and every method. Returns that (world, noise)."""
    ours = [r for r in runs if r.method == "planodom"]
    if not ours:
        return None
    worst = max(ours, key=lambda r: np.nan_to_num(_ratio(runs, "ate_xy_m", r), nan=-1.0))
    here = [r for r in runs if (r.world, r.noise) == (worst.world, worst.noise)]
    tracks = [(f"{r.method} (ATE {r.metrics['ate_xy_m']:.2f} m)", r.poses, COLOURS.get(r.method))
              for r in here]  # fmt: skip
    title = f"world {worst.world} ({worst.kind}, {worst.family}), sigma {worst.noise * 1000:g} mm"
    plot_panels([(title, worst.gt_poses[:, :3, 3], tracks)], path)
    return worst.world, worst.noise


def run_generalisation_experiment(
    out: str | Path | None = None,
    n_worlds: int = 20,
    noise_levels: Sequence[float] = NOISE_LEVELS,
    n_epochs: int | None = 300,
    methods: Sequence[str] = DEFAULT_METHODS,
    config: PlanodomConfig | None = None,
    progress: Callable[[str], None] | None = None,
    rigs: Sequence[str] = ("rig2d", "lidar"),
    first_world: int = 0,
    motion: str = "vehicle",
) -> GeneralisationExperiment:
    """Run the experiment; write its tables and plot to ``out`` when given.

    Args:
        n_worlds: worlds ``first_world`` .. ``first_world + n_worlds - 1``
            (:func:`world_for`), those whose rig class (``"rig2d"`` for even worlds,
            ``"lidar"`` for odd ones) is in ``rigs``.
        noise_levels: m.
        n_epochs: epochs per run (None: one lap of each world).
        methods: any of :data:`METHODS` (planodom, planodom-wocsc, planodom-sda-mean,
            planodom-offline, oracle, kiss-icp, open3d-icp; kiss-icp is skipped with a
            note when not installed).
        config: planodom's base configuration. progress: called with short messages.
        first_world: the first world's index (worlds from 20 on were never looked at
            while planodom's defaults were chosen: a held-out set).
        motion: "vehicle" or "handheld" (every world a hand-held lidar's, :func:`world_for`).
    """
    base = config or PlanodomConfig()
    say = progress or (lambda msg: None)
    if "kiss-icp" in methods and not kiss_available():
        say("kiss-icp is not installed (uv sync --extra baselines): skipped")
    strange = [m for m in methods if m not in METHODS]
    if strange or not methods:
        raise ValueError(f"methods: {strange or 'none'}; expected some of {', '.join(METHODS)}")
    unknown = set(rigs) - {"rig2d", "lidar"}
    if unknown or not rigs:
        raise ValueError(f"rigs: {sorted(unknown) or 'none'}; expected rig2d and/or lidar")
    if first_world < 0:
        raise ValueError(f"first_world: {first_world}; expected >= 0")
    span = range(first_world, first_world + n_worlds)
    indices = [i for i in span if rig_class(i, motion) in rigs]
    runs: list[MethodRun] = []
    for i in indices[:2]:  # the first two worlds run: one of each rig class with both
        _warm_up(world_for(i, motion), base, methods)
    result = GeneralisationExperiment(runs, {})
    for i in indices:
        world = world_for(i, motion)
        for noise in noise_levels:
            runs += run_world(world, float(noise), n_epochs, base, methods, say)
        # the tables so far after every world: an interrupted run keeps what it measured
        result.tables = {"runs": run_rows(runs), "summary": summary_rows(runs)}
        if out is not None:
            result.files = _write(Path(out), result.tables, base)
    if out is not None:
        result.files = _write(Path(out), result.tables, base)
        if plot_worst(runs, Path(out) / "worst_world.png") is not None:
            result.files["worst_world"] = Path(out) / "worst_world.png"
    return result


def _write(out: Path, tables: Mapping[str, Rows], config: PlanodomConfig) -> dict[str, Path]:
    """The tables and the configuration in ``out``; their paths."""
    out.mkdir(parents=True, exist_ok=True)
    files = write_tables(out, tables, markdown={"summary": summary_markdown})
    files["config"] = out / "config.yaml"
    config.to_yaml(files["config"])
    return files
