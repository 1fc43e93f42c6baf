"""planodom's odometry against point-based peers on the same recordings, in one run.

Per dataset (anything :func:`planodom.datasets.recording.open_recording` reads), every
scan is read once into memory (reading is excluded from the timings), then each method
runs over the same scans:

- ``planodom``: :func:`planodom.odometry.run_odometry` with the given config (default
  pipeline); ``planodom-wocsc``: the same with the paper's ``"wocsc"`` pipeline (optional);
- ``kiss-icp``: KISS-ICP (optional dependency group ``baselines``; skipped with a note when
  it is not installed), default configuration, no deskewing (the scans carry no times);
- ``open3d-icp``: open3d's point-to-plane ``registration_icp`` scan to scan (0.5 m voxels,
  normals from 1.5 m / 30 neighbours, 1 m correspondence distance, constant-velocity
  initial guess).

For each: per-scan rotation and translation error rms and p95 (the error of
``inv(T_ref_rel) @ T_est_rel`` per consecutive pair), horizontal drift (final position
error over the distance travelled; NaN for a reference that does not move, a still
sensor) and the final horizontal position error itself, bad epochs (planodom:
unresolved or degenerate) and gross errors (over 1 deg or 20 cm, every method), epochs
per second, and the resident memory at the start (planodom: after a tenth of the epochs,
its compiled kernels loaded) and end of the method's run (flat memory; the scans in
memory are part of it). Options
for large-motion checks: ``step`` (every k-th scan), ``turn_deg`` (every scan turned a
further angle about the base z axis, or alternately +angle / 0 with ``alternate``).
Writes ``baselines.md``, ``baselines.csv`` and ``trajectories.png`` (top views of all
trajectories). planodom's compiled kernels are loaded before its timing starts.

The reference is the recording's ``poses.tum`` (or the bag's reference topic); a recording
without one is compared against KISS-ICP's trajectory instead, a proxy with its own
errors (the table's note says so; without KISS-ICP installed such a recording is
refused).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.config import PlanodomConfig
from planodom.errors import DatasetError
from planodom.experiments.plots import plot_panels
from planodom.experiments.tables import ExperimentResult, markdown_table, write_tables
from planodom.geometry import invert_transform
from planodom.scan import Scan

#: Gross per-scan errors: above either limit (deg, m).
GROSS_DEG, GROSS_M = 1.0, 0.2
COLOURS = {"planodom": "magenta", "planodom-wocsc": "tab:green", "kiss-icp": "tab:orange",
           "open3d-icp": "tab:red"}  # fmt: skip


@dataclass
class Scans:
    """One dataset's scans in memory and its reference. poses: (E, 4, 4) T_world_base."""

    name: str
    scans: list[Scan]
    poses: np.ndarray | None
    times: np.ndarray
    rig: object


@dataclass
class MethodRun:
    """One method on one dataset: relative poses (E-1, 4, 4), seconds, notes."""

    dataset: str
    method: str
    relative: np.ndarray
    seconds: float
    bad: int | None
    rss_mb: tuple[float, float]


def rss_mb() -> float:
    """Resident memory of this process (MB; NaN where /proc is absent)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return float("nan")


def load_scans(path: Path, limit: int | None, step: int, turn_deg: float, alternate: bool) -> Scans:
    """The dataset's scans (every ``step``-th, at most ``limit`` read) and reference (None
    without one), optionally turned about z by ``k * turn_deg`` (or ``(k % 2) *
    turn_deg``)."""
    from planodom.datasets.recording import open_recording

    ds = open_recording(path)
    n = len(ds) if limit is None else min(limit, len(ds))
    index = list(range(0, n, step))
    poses = None if ds.gt_poses is None else np.asarray(ds.gt_poses)[index]
    scans = [ds[k] for k in index]
    times = np.asarray(ds.times)[index]
    if turn_deg:
        k = np.arange(len(index))
        angle = (k % 2 if alternate else k) * turn_deg
        A = np.tile(np.eye(4), (len(index), 1, 1))
        A[:, :3, :3] = Rotation.from_euler("z", angle[:, None], degrees=True).as_matrix()
        origins = getattr(ds.rig, "sensor_origins", None)
        if origins is not None and np.abs(origins[:, :2]).max() > 1e-9:
            raise DatasetError(f"{path}: --turn needs a sensor above the base origin")
        scans = [Scan(s.points @ A[i, :3, :3], s.ring, s.t, s.label) for i, s in enumerate(scans)]
        poses = None if poses is None else poses @ A
    return Scans(Path(path).name, scans, poses, times, ds.rig)


def run_planodom(data: Scans, config: PlanodomConfig) -> tuple[np.ndarray, float, int, float]:
    """Relative poses, seconds, bad epochs and the RSS (MB) after a tenth of the epochs
    (compiled kernels loaded: the start of the flat-memory check)."""
    from planodom.extraction import extract_planes
    from planodom.odometry import run_odometry

    # Load the compiled kernels first (numba's cache), excluded from the timing as reading is:
    # the extraction's, then the odometry's (and its modules) by a run over the first
    # epochs (on the 83-epoch libwave lot they were 10-15 % of the timed run).
    extract_planes(data.scans[0], config.updated(config.planemap.extraction_changes()).extraction)
    run_odometry(data.scans[:3], config, data.rig, times=data.times[:3])  # type: ignore[arg-type]
    early = [float("nan")]

    def sample(k: int, n: int) -> None:
        if k == max(1, n // 10):
            early[0] = rss_mb()

    t0 = time.perf_counter()
    run = run_odometry(data.scans, config, data.rig, times=data.times, progress=sample)  # type: ignore[arg-type]
    seconds = time.perf_counter() - t0
    rel = np.array([r.T_prev_curr for r in run.results[1:] if r is not None]).reshape(-1, 4, 4)
    return rel, seconds, run.n_unresolved + run.n_degenerate, early[0]


def run_kiss(data: Scans) -> tuple[np.ndarray, float]:
    from kiss_icp.config import load_config
    from kiss_icp.kiss_icp import KissICP

    cfg = load_config(None)
    cfg.data.deskew = False
    odo = KissICP(cfg)
    poses = []
    t0 = time.perf_counter()
    for s in data.scans:
        odo.register_frame(s.points, np.array([]))
        poses.append(odo.last_pose.copy())
    seconds = time.perf_counter() - t0
    P = np.array(poses)
    return invert_transform(P[:-1]) @ P[1:], seconds


def run_open3d(data: Scans, voxel: float = 0.5, max_dist: float = 1.0) -> tuple[np.ndarray, float]:
    from planodom._open3d import o3d

    reg = o3d.pipelines.registration
    est, prev, guess = [], None, np.eye(4)
    t0 = time.perf_counter()
    for s in data.scans:
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(s.points)).voxel_down_sample(voxel)
        pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=3 * voxel, max_nn=30))
        if prev is not None:  # source = current, target = previous: T_prev_curr
            r = reg.registration_icp(pc, prev, max_dist, guess,
                                     reg.TransformationEstimationPointToPlane(),
                                     reg.ICPConvergenceCriteria(max_iteration=50))  # fmt: skip
            est.append(np.asarray(r.transformation).copy())
            guess = est[-1]
        prev = pc
    return np.array(est).reshape(-1, 4, 4), time.perf_counter() - t0


def errors(rel: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-pair rotation (deg) and translation (m) errors of ``inv(ref) @ rel``."""
    E = invert_transform(ref) @ rel
    cos = np.clip((np.trace(E[:, :3, :3], axis1=1, axis2=2) - 1) / 2, -1, 1)
    return np.degrees(np.arccos(cos)), np.linalg.norm(E[:, :3, 3], axis=1)


def chain(rel: np.ndarray) -> np.ndarray:
    """(E, 4, 4) poses from relative poses, the first at identity."""
    out = [np.eye(4)]
    for T in rel:
        out.append(out[-1] @ T)
    return np.array(out)


def row_of(m: MethodRun, ref: np.ndarray) -> dict[str, object]:
    """One table row (module docstring)."""
    r, t = errors(m.relative, ref)
    est, gt = chain(m.relative), chain(ref)
    length = float(np.sum(np.linalg.norm(ref[:, :2, 3], axis=1)))
    end = float(np.linalg.norm(est[-1, :2, 3] - gt[-1, :2, 3]))
    drift = end / length if length > 0 else float("nan")
    return {
        "dataset": m.dataset,
        "method": m.method,
        "rot_rms_deg": float(np.sqrt(np.mean(r**2))),
        "rot_p95_deg": float(np.percentile(r, 95)),
        "trans_rms_cm": float(100 * np.sqrt(np.mean(t**2))),
        "trans_p95_cm": float(100 * np.percentile(t, 95)),
        "drift_pct": 100 * drift,
        "end_cm": 100 * end,
        "bad_epochs": "-" if m.bad is None else f"{m.bad}/{len(r)}",
        "gross": f"{int(np.count_nonzero((r > GROSS_DEG) | (t > GROSS_M)))}/{len(r)}",
        "epochs_per_s": len(r) / m.seconds if m.seconds > 0 else float("nan"),
        "rss_mb": f"{m.rss_mb[0]:.0f}->{m.rss_mb[1]:.0f}",
    }


def _methods(config: PlanodomConfig, wocsc: bool) -> list[tuple[str, Callable]]:
    methods: list[tuple[str, Callable]] = [("planodom", lambda d: run_planodom(d, config))]
    if wocsc:
        paper = config.updated({"odometry.pipeline": "wocsc"}, source="baselines")
        methods.append(("planodom-wocsc", lambda d: run_planodom(d, paper)))
    methods += [("kiss-icp", run_kiss), ("open3d-icp", run_open3d)]
    return methods


def run_baselines_experiment(
    datasets: Sequence[Path],
    out: Path,
    config: PlanodomConfig | None = None,
    *,
    wocsc: bool = False,
    limit: int | None = None,
    step: int = 1,
    turn_deg: float = 0.0,
    alternate: bool = False,
    progress: Callable[[str], None] | None = None,
) -> ExperimentResult[MethodRun]:
    """The comparison of the module docstring; files in ``out``."""
    say = progress or (lambda _m: None)
    config = config or PlanodomConfig()
    out.mkdir(parents=True, exist_ok=True)
    runs: list[MethodRun] = []
    rows: list[dict[str, object]] = []
    notes: list[str] = []
    panels = []
    for path in datasets:
        data = load_scans(Path(path), limit, step, turn_deg, alternate)
        methods = _methods(config, wocsc)
        if data.poses is None:  # KISS-ICP's trajectory is the reference: it runs first
            methods.sort(key=lambda m: m[0] != "kiss-icp")
        ref: np.ndarray | None = None
        if data.poses is not None:
            ref = invert_transform(data.poses[:-1]) @ data.poses[1:]
        first = len(runs)
        tracks = []
        for name, fn in methods:
            say(f"{data.name}: {name} on {len(data.scans)} scans")
            before = rss_mb()
            try:
                result = fn(data)
            except ImportError as exc:
                notes.append(f"{name} skipped ({exc.name or exc} not installed: "
                             "uv sync --extra baselines)")  # fmt: skip
                continue
            bad = result[2] if len(result) > 2 else None
            start = result[3] if len(result) > 3 else before
            m = MethodRun(data.name, name, result[0], result[1], bad, (start, rss_mb()))
            if ref is None:
                if name != "kiss-icp":
                    raise DatasetError(f"{path}: no reference trajectory (poses.tum), and "
                                       "KISS-ICP, its proxy, is not installed")  # fmt: skip
                ref = m.relative
                notes.append(f"{data.name}: no reference trajectory: errors against KISS-ICP's "
                             "trajectory (a proxy, with its own errors)")  # fmt: skip
            runs.append(m)
            tracks.append((name, chain(m.relative), COLOURS.get(name)))
        if ref is None:
            raise DatasetError(f"{path}: no reference trajectory (poses.tum) and no method ran")
        rows.extend(row_of(m, ref) for m in runs[first:])
        panels.append((data.name, chain(ref)[:, :3, 3], tracks))
    text = markdown_table(rows) + "".join(f"\n{n}\n" for n in sorted(set(notes)))
    files = write_tables(out, {"baselines": rows}, {"baselines": lambda _r: text})
    if panels:
        files["trajectories"] = out / "trajectories.png"
        plot_panels(panels, files["trajectories"])
    return ExperimentResult(runs, {"baselines": rows}, files)
