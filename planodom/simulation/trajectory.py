"""Continuous-time ground truth ``T_world_base(t)``, exactly evaluable at any time.

Every trajectory maps times ``t`` (T,) in seconds to poses (T, 4, 4) with
:meth:`Trajectory.poses`; the simulator evaluates it once per beam. Orientation is
``R = Rz(yaw) Ry(pitch) Rx(roll)`` (as :func:`planodom.geometry.transform_from_rpy_xyz`).

- :class:`WaypointTrajectory`: a C2 cubic spline through 2D waypoints (periodic for a
  closed loop), travelled at constant speed (arc length inverted by a second spline),
  yaw along the path, plus small roll / pitch / heave oscillations so that all three
  rotation rates are exercised.
- :class:`TwistTrajectory`: ``T0 @ exp(t xi)`` for a constant body twist (closed form),
  the motion model of deskewing; :class:`StaticTrajectory` stands still.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from planodom.errors import GeometryError
from planodom.geometry import se3_exp
from planodom.simulation.worlds import PAPER_LOOP_ROUTE, URBAN_CANYON_ROUTE


def _rotations(cr, sr, cp, sp, cy, sy) -> np.ndarray:
    """``Rz Ry Rx`` (T, 3, 3) from the cosines and sines (T,) of roll, pitch and yaw.

    Our own product rather than scipy's Euler angles: the path gives the yaw's cosine and
    sine directly (the unit tangent), with no angle to recover, and the simulator
    evaluates it once per beam (cheap, and the simulated scans stay as recorded)."""
    spcr, spsr = sp * cr, sp * sr
    rows = (cy * cp, cy * spsr - sy * cr, cy * spcr + sy * sr,
            sy * cp, sy * spsr + cy * cr, sy * spcr - cy * sr,
            -sp, cp * sr, cp * cr)  # fmt: skip
    return np.stack(rows, axis=-1).reshape(-1, 3, 3)


def _cubic(x: np.ndarray, c: np.ndarray, u: np.ndarray, deriv: bool = True):
    """Value (and first derivative) of a cubic piecewise polynomial (scipy ``PPoly``
    layout: breakpoints ``x`` (n+1,), coefficients ``c`` (4, n, ...)) at ``u`` (T,)."""
    i = np.clip(np.searchsorted(x, u, side="right") - 1, 0, len(x) - 2)
    h = (u - x.take(i)).reshape((-1,) + (1,) * (c.ndim - 2))
    c0, c1, c2, c3 = np.take(c, i, axis=1)
    value = ((c0 * h + c1) * h + c2) * h + c3
    return (value, (3.0 * c0 * h + 2.0 * c1) * h + c2) if deriv else value


class Trajectory(ABC):
    """Ground truth ``T_world_base(t)``; ``duration`` (s) is one lap or the whole path.
    ``platform``: what moves the base, as a dataset of it declares it
    (:data:`planodom.rig.PLATFORMS`, None: not stated)."""

    duration: float
    platform: str | None = None

    @abstractmethod
    def poses(self, t: np.ndarray) -> np.ndarray:
        """Poses ``T_world_base`` (T, 4, 4) at times ``t`` (T,), seconds."""

    def pose(self, t: float) -> np.ndarray:
        """Single pose ``T_world_base`` (4, 4) at time ``t`` (s)."""
        return self.poses(np.array([float(t)]))[0]

    def rotations_translations(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations (T, 3, 3) and translations (T, 3), metres, of :meth:`poses` at ``t``."""
        T = self.poses(t)
        return T[:, :3, :3], T[:, :3, 3]


def _assemble(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.zeros((len(R), 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = R, p, 1.0
    return T


@dataclass(frozen=True)
class Sway:
    """Small oscillations on top of the path: amplitudes (rad, m) and frequencies (Hz)."""

    roll: float = np.deg2rad(1.5)
    roll_hz: float = 0.37
    pitch: float = np.deg2rad(1.0)
    pitch_hz: float = 0.23
    heave: float = 0.02
    heave_hz: float = 0.5

    def __post_init__(self) -> None:
        if not (abs(self.roll) < np.pi / 2 and abs(self.pitch) < np.pi / 2):
            raise GeometryError("sway roll and pitch amplitudes must be below 90 degrees")

    @classmethod
    def still(cls) -> Sway:
        """No oscillation at all."""
        return cls(roll=0.0, pitch=0.0, heave=0.0)

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """roll (T,), pitch (T,) in rad and heave (T,) in m at times ``t`` (T,), s."""
        w = 2.0 * np.pi * t
        return (
            self.roll * np.sin(self.roll_hz * w),
            self.pitch * np.sin(self.pitch_hz * w + 1.0),
            self.heave * np.sin(self.heave_hz * w + 2.0),
        )


class WaypointTrajectory(Trajectory):
    """Constant-speed drive along a cubic spline through 2D waypoints.

    Args:
        waypoints: (W, 2) metres; W >= 3 for a closed loop, W >= 2 otherwise.
        speed: m/s along the path. height: z of the base (m). closed: periodic loop.
        sway: roll / pitch / heave oscillations (:class:`Sway`, default ``Sway()``;
            ``Sway.still()`` for none).

    ``duration`` is one lap (closed) or the path (open). Open paths hold the last pose
    after the end and the first before the start; closed loops repeat. A vehicle: its
    base's x axis along the path (``platform`` "vehicle").
    """

    platform: str | None = "vehicle"

    def __init__(
        self,
        waypoints: np.ndarray,
        speed: float = 2.0,
        height: float = 1.0,
        closed: bool = True,
        sway: Sway | None = None,
    ) -> None:
        w = np.asarray(waypoints, dtype=np.float64)
        if w.ndim != 2 or w.shape[1] != 2 or len(w) < (3 if closed else 2) or speed <= 0:
            raise GeometryError("waypoints must be (W, 2), W >= 3 closed / 2 open; speed > 0")
        self.speed, self.height, self.closed = float(speed), float(height), closed
        self.sway = sway if sway is not None else Sway()
        if closed:
            w = np.vstack([w, w[:1]])
        u = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(w, axis=0), axis=1))])
        self._path = CubicSpline(u, w, bc_type="periodic" if closed else "natural")
        # Arc length s(u) on a fine grid (Simpson per cell), inverted by a spline u(s).
        uu = np.linspace(0.0, u[-1], max(2000, int(u[-1] * 20)))
        mid = 0.5 * (uu[1:] + uu[:-1])
        sp = [np.linalg.norm(self._path(x, 1), axis=1) for x in (uu[:-1], mid, uu[1:])]
        ds = np.diff(uu) / 6.0 * (sp[0] + 4.0 * sp[1] + sp[2])
        s = np.concatenate([[0.0], np.cumsum(ds)])
        self.length = float(s[-1])
        self.duration = self.length / self.speed
        self._u_span = float(u[-1])
        if closed:  # u(s) - s * U / L is periodic: a periodic spline keeps the loop C2
            g = uu - s * self._u_span / self.length
            g[-1] = g[0]
            self._u_of_s = CubicSpline(s, g, bc_type="periodic")
        else:
            self._u_of_s = CubicSpline(s, uu)

    def _param(self, t: np.ndarray) -> np.ndarray:
        """Spline parameter u (T,) at times t (T,): arc length s = speed t inverted."""
        s = self.speed * t
        if self.closed:
            s = np.mod(s, self.length)
            return _cubic(self._u_of_s.x, self._u_of_s.c, s, False) + s * (
                self._u_span / self.length
            )
        return _cubic(self._u_of_s.x, self._u_of_s.c, np.clip(s, 0.0, self.length), False)

    def _heading(self, dxy: np.ndarray, t: np.ndarray) -> np.ndarray:
        """(cos yaw, sin yaw) (T, 2) from the path's tangents ``dxy`` (T, 2) at times ``t``."""
        return dxy / np.hypot(dxy[:, 0], dxy[:, 1])[:, None]

    def _sway_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """roll, pitch (rad) and heave (m), each (T,), at times ``t`` (T,), s."""
        return self.sway.at(t)

    def rotations_translations(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations (T, 3, 3) and translations (T, 3), metres, at times ``t`` (T,), s."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        xy, dxy = _cubic(self._path.x, self._path.c, self._param(t))
        heading = self._heading(dxy, t)
        roll, pitch, heave = self._sway_at(t)
        sr, sp = np.sin(roll), np.sin(pitch)  # |roll|, |pitch| < pi / 2: cos = sqrt(1 - sin^2)
        cr, cp = np.sqrt(1.0 - sr * sr), np.sqrt(1.0 - sp * sp)
        R = _rotations(cr, sr, cp, sp, heading[:, 0], heading[:, 1])
        return R, np.column_stack([xy, self.height + heave])

    def poses(self, t: np.ndarray) -> np.ndarray:
        """Poses ``T_world_base`` (T, 4, 4) at times ``t`` (T,), seconds."""
        return _assemble(*self.rotations_translations(t))


@dataclass(frozen=True)
class SpeedProfile:
    """Speed changes over a lap: ``s(t) = v t + sum_m a_m (sin(2 pi m t / T + phi_m) -
    sin(phi_m))`` (m) with ``T`` the lap time at the mean speed ``v``, so that a lap still
    takes ``T`` and the profile repeats every lap. ``harmonics`` are (m, a_m in metres,
    phi_m in rad); the speed stays positive when ``sum 2 pi m |a_m| / T < v``."""

    harmonics: tuple[tuple[int, float, float], ...] = ()

    def distance(self, t: np.ndarray, speed: float, lap_s: float) -> np.ndarray:
        """Arc length (T,) in metres travelled at times ``t`` (T,), seconds."""
        s = speed * t
        for m, a, phi in self.harmonics:
            s = s + a * (np.sin(2.0 * np.pi * m * t / lap_s + phi) - np.sin(phi))
        return s


class RouteTrajectory(WaypointTrajectory):
    """A :class:`WaypointTrajectory` with speed changes (:class:`SpeedProfile`) and a sloped
    ground: the base stays ``height`` m above the ground plane ``z = gx x + gy y`` and its
    z axis follows the ground's normal (before the sway)."""

    def __init__(
        self,
        waypoints: np.ndarray,
        speed: float = 2.0,
        height: float = 1.0,
        sway: Sway | None = None,
        profile: SpeedProfile | None = None,
        gradient: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        super().__init__(waypoints, speed=speed, height=height, closed=True, sway=sway)
        self.profile = profile or SpeedProfile()
        self.gradient = (float(gradient[0]), float(gradient[1]))
        n = np.array([-self.gradient[0], -self.gradient[1], 1.0])
        n /= np.linalg.norm(n)
        axis = np.cross([0.0, 0.0, 1.0], n)
        angle = np.arcsin(min(1.0, float(np.linalg.norm(axis))))
        w = axis / np.linalg.norm(axis) * angle if angle > 0 else np.zeros(3)
        self._tilt = se3_exp(np.r_[w, 0.0, 0.0, 0.0])[:3, :3]  # takes +z to the normal

    def _param(self, t: np.ndarray) -> np.ndarray:
        s = np.mod(self.profile.distance(t, self.speed, self.duration), self.length)
        u = _cubic(self._u_of_s.x, self._u_of_s.c, s, False)
        return u + s * (self._u_span / self.length)

    def rotations_translations(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations (T, 3, 3) and translations (T, 3), metres, at times ``t`` (T,), s."""
        R, p = super().rotations_translations(t)
        p[:, 2] += self.gradient[0] * p[:, 0] + self.gradient[1] * p[:, 1]
        return np.matmul(self._tilt, R), p


class TwistTrajectory(Trajectory):
    """``T_world_base(t) = T0 @ exp(t * xi)``: constant body twist ``xi = (w, v)`` (6,),
    rad/s and m/s, from ``T0`` (4, 4) at t = 0 (closed-form SE(3) exponential)."""

    def __init__(self, T0: np.ndarray, xi: np.ndarray, duration: float = 10.0) -> None:
        self.T0 = np.asarray(T0, dtype=np.float64)
        self.xi = np.asarray(xi, dtype=np.float64).reshape(6)
        self.duration = float(duration)

    def poses(self, t: np.ndarray) -> np.ndarray:
        """Poses ``T_world_base`` (T, 4, 4) at times ``t`` (T,), seconds."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        return self.T0 @ se3_exp(t[:, None] * self.xi)


class StaticTrajectory(Trajectory):
    """A vehicle standing still at ``T`` (4, 4)."""

    def __init__(self, T: np.ndarray, duration: float = 10.0) -> None:
        self.T = np.asarray(T, dtype=np.float64)
        self.duration = float(duration)

    def poses(self, t: np.ndarray) -> np.ndarray:
        """``T`` repeated: (T, 4, 4)."""
        return np.repeat(self.T[None], len(np.atleast_1d(t)), axis=0)


def paper_loop_trajectory(speed: float = 2.0, sway: Sway | None = None) -> WaypointTrajectory:
    """One lap (about 150 m) of the paper loop's route at ``speed`` m/s, base 1 m above ground."""
    return WaypointTrajectory(PAPER_LOOP_ROUTE, speed=speed, closed=True, sway=sway)


def urban_canyon_trajectory(speed: float = 2.0, sway: Sway | None = None) -> WaypointTrajectory:
    """The 150 m street of the urban canyon, once, at ``speed`` m/s."""
    return WaypointTrajectory(URBAN_CANYON_ROUTE, speed=speed, closed=False, sway=sway)
