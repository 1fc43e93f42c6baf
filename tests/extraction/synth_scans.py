"""A small, independent scan generator for the extraction tests.

Rectangular walls, a vehicle moving with a constant body twist, tilted 2D scanners that
sweep several times per epoch, and a spinning multi-beam lidar. Points are produced in
the base frame of their own acquisition time, with their times, rings and true wall ids,
exactly like the simulator's output, but without depending on it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.geometry import se3_exp, transform_from_rpy_xyz
from planodom.scan import Scan


@dataclass(frozen=True)
class Rect:
    """A wall: centre (3,), unit normal (3,), in-plane unit axis u (3,), half sizes (m)."""

    center: np.ndarray
    normal: np.ndarray
    u: np.ndarray
    half_u: float
    half_v: float

    @property
    def v(self) -> np.ndarray:
        return np.cross(self.normal, self.u)

    @property
    def offset(self) -> float:
        return float(-self.normal @ self.center)


def rect(center, normal, up=(0.0, 0.0, 1.0), half_u=5.0, half_v=2.0) -> Rect:
    """A rectangle with axis u perpendicular to ``up`` (horizontal for walls)."""
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    u = np.cross(np.asarray(up, float), n)
    if np.linalg.norm(u) < 1e-9:
        u = np.cross([1.0, 0.0, 0.0], n)
    u = u / np.linalg.norm(u)
    return Rect(np.asarray(center, float), n, u, half_u, half_v)


def default_scene() -> list[Rect]:
    """Ground (id 0) with the base origin on it, four walls of several orientations."""
    return [
        rect([5, 0, 0], [0, 0, 1], up=[1, 0, 0], half_u=30, half_v=30),  # ground z = 0
        rect([6, 7, 2], [0, -1, 0], half_u=8),  # left wall, along the road
        rect([12, -1, 2], [-1, 0, 0], half_u=6),  # wall across the road, ahead
        rect([4, -6, 2], [-np.sin(0.5), np.cos(0.5), 0], half_u=5),  # oblique, right
        rect([-9, 2, 2], [np.cos(0.3), -np.sin(0.3), 0], half_u=6),  # behind, slanted
    ]


def cast(rects: list[Rect], origins: np.ndarray, dirs: np.ndarray):
    """Ranges (R,) (inf for no hit) and hit ids (R,) of rays against the rectangles."""
    best = np.full(len(origins), np.inf)
    ids = np.full(len(origins), -1)
    for k, r in enumerate(rects):
        den = dirs @ r.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (r.normal @ r.center - origins @ r.normal) / den
            hit = origins + t[:, None] * dirs
        rel = hit - r.center
        ok = (
            (t > 1e-6)
            & (np.abs(rel @ r.u) <= r.half_u)
            & (np.abs(rel @ r.v) <= r.half_v)
            & (np.abs(den) > 1e-9)
        )
        better = ok & (t < best)
        best[better] = t[better]
        ids[better] = k
    return best, ids


def default_rig() -> list[np.ndarray]:
    """T_base_scanner of four tilted 2D scanners: a forward and a backward isoclinal pair."""
    out = []
    for yaw, x in ((0.0, 1.0), (np.pi, -1.0)):
        for roll in (0.5, -0.5):
            out.append(transform_from_rpy_xyz(roll, 0.25, yaw, x, 0.0, 1.5))
    return out


def _poses(times: np.ndarray, twist: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (N, 3, 3) and translations (N, 3) of T_ref_t = exp(t xi) for every time."""
    if twist is None:
        return np.tile(np.eye(3), (len(times), 1, 1)), np.zeros((len(times), 3))
    T = se3_exp(np.asarray(times, dtype=np.float64)[:, None] * np.asarray(twist)[None])
    return T[:, :3, :3], T[:, :3, 3]


def _rotate(rot: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``rot[i] @ v[i]`` for rotations (N, 3, 3) and vectors (N, 3) (or (3,) for all)."""
    return np.einsum("nij,nj->ni", rot, np.broadcast_to(v, (len(rot), 3)))


def scan_rig(
    rects: list[Rect],
    twist: np.ndarray | None = None,
    sigma: float = 0.0,
    seed: int = 0,
    rig: list[np.ndarray] | None = None,
    n_sweeps: int = 7,
    rate_hz: float = 75.0,
    step_deg: float = 1.0,
) -> Scan:
    """One epoch of a 2D-scanner rig; the world frame is the base frame at t = 0.

    Each scanner sweeps ``n_sweeps`` times (-90..90 deg in the first half of each 1/rate
    period). Range noise is Gaussian, ``sigma`` metres, along the beam.
    """
    rig = default_rig() if rig is None else rig
    rng = np.random.default_rng(seed)
    ang = np.radians(np.arange(-90.0, 90.0 + 1e-9, step_deg))
    beam = np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)])
    pts, rings, times, labels = [], [], [], []
    for k, T_bs in enumerate(rig):
        t = (
            np.arange(n_sweeps)[:, None] / rate_hz + np.linspace(0, 0.5 / rate_hz, len(ang))
        ).ravel()
        d_base = np.tile(beam @ T_bs[:3, :3].T, (n_sweeps, 1))
        o_base = np.broadcast_to(T_bs[:3, 3], d_base.shape).copy()
        rot, trans = _poses(t, twist)
        o_world = _rotate(rot, o_base) + trans
        d_world = _rotate(rot, d_base)
        r, ids = cast(rects, o_world, d_world)
        r = r + sigma * rng.standard_normal(len(r))
        ok = np.isfinite(r) & (r > 0)
        pts.append(o_base[ok] + r[ok, None] * d_base[ok])
        rings.append(np.full(np.count_nonzero(ok), k))
        times.append(t[ok])
        labels.append(ids[ok])
    return Scan(
        np.concatenate(pts), np.concatenate(rings), np.concatenate(times), np.concatenate(labels)
    )


def scan_lidar(
    rects: list[Rect],
    twist: np.ndarray | None = None,
    sigma: float = 0.0,
    seed: int = 0,
    n_beams: int = 32,
    n_azimuth: int = 1024,
    height: float = 1.8,
    period_s: float = 0.1,
    with_ring: bool = True,
) -> Scan:
    """One revolution of a spinning lidar at (0, 0, height), beams from -15 to +15 deg."""
    rng = np.random.default_rng(seed)
    elev = np.radians(np.linspace(-15.0, 15.0, n_beams))
    az = np.linspace(0, 2 * np.pi, n_azimuth, endpoint=False)
    E, A = np.meshgrid(elev, az)  # (n_az, n_beams): azimuth-major, time along azimuth
    d_base = np.column_stack(
        [(np.cos(E) * np.cos(A)).ravel(), (np.cos(E) * np.sin(A)).ravel(), np.sin(E).ravel()]
    )
    t = np.repeat(az / (2 * np.pi) * period_s, n_beams)
    ring = np.tile(np.arange(n_beams), n_azimuth)
    o_base = np.broadcast_to([0.0, 0.0, height], d_base.shape).copy()
    rot, trans = _poses(t, twist)
    r, ids = cast(rects, _rotate(rot, o_base) + trans, _rotate(rot, d_base))
    r = r + sigma * rng.standard_normal(len(r))
    ok = np.isfinite(r) & (r > 0)
    pts = o_base[ok] + r[ok, None] * d_base[ok]
    return Scan(pts, ring[ok] if with_ring else None, t[ok], ids[ok])


def planes_in_base(rects: list[Rect]) -> dict[int, tuple[np.ndarray, float]]:
    """True (n, d) of each wall in the base frame at t = 0 (the world frame here)."""
    return {k: (r.normal, r.offset) for k, r in enumerate(rects)}


def plane_errors(planes, truth: dict[int, tuple[np.ndarray, float]]) -> tuple[float, float]:
    """Largest angle (rad) and offset error (m) of extracted ``planes`` against the true
    planes ``truth`` (by ``truth_id``, as :func:`planes_in_base` gives them), sign-free."""
    ang = off = 0.0
    for p in planes:
        n, d = truth[p.truth_id]
        s = np.sign(p.normal @ n)
        ang = max(ang, float(np.arccos(min(1.0, abs(p.normal @ n)))))
        off = max(off, abs(s * p.offset - d))
    return ang, off
