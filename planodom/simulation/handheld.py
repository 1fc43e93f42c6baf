"""A hand-held sensor carried along a route: walking with stops, the sensor's yaw swinging
about the walking direction, roll / pitch sway and a vertical bob at the step frequency.

    traj = random_handheld(rng, waypoints)       # drawn; closes after one lap in all DoF
    traj = HandheldTrajectory(waypoints, speed=1.2, swing=Swing(np.deg2rad(40), 0.8))

Every oscillation has a whole number of cycles per lap and the stops repeat each lap, so
the pose after one lap (``duration`` s) is the pose at t = 0 (as :class:`Sway` on a
vehicle's route). Orientation ``R = tilt Rz(heading + swing) Ry(pitch) Rx(roll)``; the
bob (the sway's heave) is scaled by the walking speed's fraction of its full value, so it
stops with the walker, while the swing and the roll / pitch sway go on.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from planodom.errors import GeometryError
from planodom.simulation.trajectory import RouteTrajectory, Sway, _cubic

#: Drawn ranges (:func:`random_handheld`): walking speed (m/s), swing amplitude (deg),
#: swing frequency (Hz), swing's peak yaw rate (deg/s), step frequency (Hz).
WALK_SPEED_MPS = (0.8, 1.5)
SWING_AMPLITUDE_DEG = (10.0, 60.0)
SWING_HZ = (0.3, 1.5)
SWING_PEAK_RATE_DEG_S = (100.0, 300.0)
STEP_HZ = (1.6, 2.2)


@dataclass(frozen=True)
class Swing:
    """The yaw's oscillation about the walking heading: ``amplitude`` (rad) ``sin(2 pi hz
    t + phase)``; peak yaw rate ``2 pi hz amplitude`` rad/s (on top of the path's turns)."""

    amplitude: float
    hz: float
    phase: float = 0.0

    def at(self, t: np.ndarray) -> np.ndarray:
        """Yaw offset (T,) in rad at times ``t`` (T,), s."""
        return self.amplitude * np.sin(2.0 * np.pi * self.hz * t + self.phase)

    @property
    def peak_rate(self) -> float:
        """Largest yaw rate of the swing, rad/s."""
        return 2.0 * np.pi * self.hz * abs(self.amplitude)


@dataclass(frozen=True)
class Stops:
    """Where a walker stops over one lap of ``lap_s`` s: stop ``k`` starts slowing down at
    ``starts[k]`` s, reaches rest after ``ramp_s`` (speed ``v (1 + cos) / 2``), stands still
    ``holds[k]`` s and is back at full speed ``ramp_s`` later. Windows may not overlap and
    must end within the lap. Each stop costs ``ramp_s + hold`` s against walking on."""

    starts: tuple[float, ...] = ()
    holds: tuple[float, ...] = ()
    ramp_s: float = 1.5

    def __post_init__(self) -> None:
        if (
            len(self.starts) != len(self.holds)
            or self.ramp_s <= 0
            or min(self.holds, default=1) < 0
        ):
            raise GeometryError("stops: one hold (>= 0 s) per start, ramp_s > 0")
        ends = [a + 2 * self.ramp_s + h for a, h in zip(self.starts, self.holds, strict=True)]
        if any(b > a for a, b in zip(self.starts[1:], ends[:-1], strict=False)):
            raise GeometryError("stops: windows must be sorted and must not overlap")

    @property
    def lost_s(self) -> float:
        """Time (s) the stops add to a lap."""
        return float(sum(self.holds)) + len(self.starts) * self.ramp_s

    def _pieces(self, tau: np.ndarray):
        """Per stop: time into the window (T,) and the window's phases."""
        r = self.ramp_s
        for a, h in zip(self.starts, self.holds, strict=True):
            u = tau - a
            yield u, r, h

    def lost(self, tau: np.ndarray) -> np.ndarray:
        """Seconds of walking lost (T,) by lap time ``tau`` (T,), s: the integral of ``1 -
        g`` with ``g`` the speed's fraction of full speed."""
        out = np.zeros_like(tau)
        for u, r, h in self._pieces(tau):
            down = np.clip(u, 0.0, r)
            out += 0.5 * (down - r / np.pi * np.sin(np.pi * down / r))
            out += np.clip(u - r, 0.0, h)
            up = np.clip(u - r - h, 0.0, r)
            out += 0.5 * (up + r / np.pi * np.sin(np.pi * up / r))
        return out

    def fraction(self, tau: np.ndarray) -> np.ndarray:
        """The speed's fraction ``g`` (T,) of full speed at lap times ``tau`` (T,), s."""
        g = np.ones_like(tau)
        for u, r, h in self._pieces(tau):
            down = (u >= 0) & (u < r)
            g = np.where(down, 0.5 * (1.0 + np.cos(np.pi * u / r)), g)
            g = np.where((u >= r) & (u < r + h), 0.0, g)
            up = (u >= r + h) & (u < 2 * r + h)
            g = np.where(up, 0.5 * (1.0 - np.cos(np.pi * (u - r - h) / r)), g)
        return g


class HandheldTrajectory(RouteTrajectory):
    """A walker carrying the sensor along a closed route (see the module docstring).

    Args:
        waypoints: (W, 2) m, W >= 3. speed: walking speed (m/s) between stops.
        height: z (m) of the base above the ground. swing: yaw about the heading.
        sway: roll / pitch / bob (heave) oscillations; the bob is scaled by the speed's
            fraction. stops: the walker's stops in a lap (``Stops.starts`` within the lap
            of ``length / speed + stops.lost_s`` s). gradient: the ground's slope.

    ``duration`` is the lap; choose frequencies with a whole number of cycles per lap
    (:func:`random_handheld` does) for the lap to close.
    """

    platform: str | None = "handheld"

    def __init__(
        self,
        waypoints: np.ndarray,
        speed: float = 1.2,
        height: float = 0.6,
        swing: Swing | None = None,
        sway: Sway | None = None,
        stops: Stops | None = None,
        gradient: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        super().__init__(waypoints, speed=speed, height=height, sway=sway, gradient=gradient)
        self.swing = swing or Swing(0.0, 1.0)
        self.stops = stops or Stops()
        self.walk_s = self.length / self.speed
        self.duration = self.walk_s + self.stops.lost_s
        ends = [
            a + 2 * self.stops.ramp_s + h
            for a, h in zip(self.stops.starts, self.stops.holds, strict=True)
        ]
        if min(self.stops.starts, default=0.0) < 0 or max(ends, default=0.0) > self.duration:
            raise GeometryError("stops must lie within one lap")

    def distance(self, t: np.ndarray) -> np.ndarray:
        """Arc length walked (T,) in m at times ``t`` (T,), s (laps counted)."""
        laps, tau = np.divmod(np.asarray(t, dtype=np.float64), self.duration)
        return laps * self.length + self.speed * (tau - self.stops.lost(tau))

    def speed_fraction(self, t: np.ndarray) -> np.ndarray:
        """The walking speed's fraction of ``speed`` (T,) at times ``t`` (T,), s."""
        return self.stops.fraction(np.mod(np.asarray(t, dtype=np.float64), self.duration))

    def _param(self, t: np.ndarray) -> np.ndarray:
        s = np.mod(self.distance(t), self.length)
        u = _cubic(self._u_of_s.x, self._u_of_s.c, s, False)
        return u + s * (self._u_span / self.length)

    def _heading(self, dxy: np.ndarray, t: np.ndarray) -> np.ndarray:
        c, s = super()._heading(dxy, t).T
        a = self.swing.at(t)
        ca, sa = np.cos(a), np.sin(a)
        return np.column_stack([c * ca - s * sa, s * ca + c * sa])

    def _sway_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        roll, pitch, heave = super()._sway_at(t)
        return roll, pitch, heave * self.speed_fraction(t)


def _whole(rng: np.random.Generator, lo: float, hi: float, lap_s: float) -> float:
    """A frequency (Hz) in [lo, hi] with a whole number of cycles per lap of ``lap_s`` s
    (uniform over the whole numbers that fit; the nearest one when none does)."""
    n_lo, n_hi = int(np.ceil(lo * lap_s)), int(np.floor(hi * lap_s))
    n = (
        int(rng.integers(n_lo, n_hi + 1))
        if n_hi >= n_lo
        else max(1, round(0.5 * (lo + hi) * lap_s))
    )
    return n / lap_s


def swing_bounds(amplitude_deg: float) -> tuple[float, float]:
    """The swing frequencies (Hz) allowed with ``amplitude_deg``: within :data:`SWING_HZ`
    and a peak rate within :data:`SWING_PEAK_RATE_DEG_S`."""
    w = 2.0 * np.pi * amplitude_deg
    return max(SWING_HZ[0], SWING_PEAK_RATE_DEG_S[0] / w), min(
        SWING_HZ[1], SWING_PEAK_RATE_DEG_S[1] / w
    )


def random_handheld(
    rng: np.random.Generator,
    waypoints: np.ndarray,
    gradient: tuple[float, float] = (0.0, 0.0),
) -> tuple[HandheldTrajectory, dict[str, Any]]:
    """A hand-held walk along the closed route ``waypoints`` (W, 2) m, and what was drawn.

    Walking speed in :data:`WALK_SPEED_MPS`; a stop (1-4 s still, 1-2 s ramps) every 8-25 s
    of walking, the first one within the first 15 s; the swing's amplitude in
    :data:`SWING_AMPLITUDE_DEG` (from the smallest one that reaches the least peak rate
    within :data:`SWING_HZ`) and its frequency where the peak rate falls within
    :data:`SWING_PEAK_RATE_DEG_S`; roll and pitch sway 2-6 deg at 0.3-1.1 Hz (roll at half
    the step frequency or so), bob 1-4 cm at the step frequency (:data:`STEP_HZ`); the
    sensor 1.2-1.6 m above the ground (base at 0.4-0.8 m, the lidar rig's mount 0.8 m above
    it). All frequencies have a whole number of cycles per lap.
    """
    speed = float(rng.uniform(*WALK_SPEED_MPS))
    height = float(rng.uniform(0.4, 0.8))
    walk_s = RouteTrajectory(waypoints, speed=speed).duration
    ramp = float(rng.uniform(1.0, 2.0))
    starts, holds, clock, covered = [], [], 0.0, 0.0
    gap = float(rng.uniform(2.0, 15.0))
    while covered + gap + ramp + 2.0 <= walk_s:  # walking time covered, stops' ramps too
        clock, covered = clock + gap, covered + gap
        starts.append(clock)
        holds.append(float(rng.uniform(1.0, 4.0)))
        clock, covered = clock + 2.0 * ramp + holds[-1], covered + ramp
        gap = float(rng.uniform(8.0, 25.0))
    stops = Stops(tuple(starts), tuple(holds), ramp)
    lap_s = walk_s + stops.lost_s
    lo_amp = SWING_PEAK_RATE_DEG_S[0] / (2.0 * np.pi * SWING_HZ[1])
    amp_deg = float(rng.uniform(max(SWING_AMPLITUDE_DEG[0], lo_amp), SWING_AMPLITUDE_DEG[1]))
    swing = Swing(np.deg2rad(amp_deg), _whole(rng, *swing_bounds(amp_deg), lap_s),
                  float(rng.uniform(0.0, 2.0 * np.pi)))  # fmt: skip
    step_hz = _whole(rng, *STEP_HZ, lap_s)
    sway = Sway(
        roll=np.deg2rad(rng.uniform(2.0, 6.0)),
        roll_hz=_whole(rng, 0.3, 1.1, lap_s),
        pitch=np.deg2rad(rng.uniform(2.0, 6.0)),
        pitch_hz=_whole(rng, 0.3, 1.1, lap_s),
        heave=float(rng.uniform(0.01, 0.04)),
        heave_hz=step_hz,
    )
    traj = HandheldTrajectory(waypoints, speed, height, swing, sway, stops, gradient)
    desc = {"motion": "handheld", "speed_mps": speed, "swing_deg": amp_deg, "swing_hz": swing.hz,
            "swing_peak_deg_s": float(np.degrees(swing.peak_rate)), "stops": len(stops.starts),
            "step_hz": step_hz, "sensor_height_m": height + 0.8}  # fmt: skip
    return traj, desc
