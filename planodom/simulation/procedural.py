"""Procedural scenes: random closed routes with an outdoor block of buildings or an indoor
loop of corridors and rooms around them.

Every function takes a ``numpy.random.Generator`` and draws from it in a fixed order, so a
seed fixes the scene. World frame: z up; lengths in metres, angles in radians unless a name
ends in ``_deg``.

- :func:`random_route`: a closed, star-shaped loop of 2D waypoints (no self-crossing).
- :func:`outdoor_scene`: buildings with random convex footprints, yaw and heights
  (6-15 m) kept clear of the route, fences and low walls (0.8-2 m) beside it, one or two
  open stretches where only the ground and one or two walls are in range, all on a
  sloped ground plane (ids: 0 ground, 1.. buildings' walls, 5000.. fences, 6000.. lone
  walls of the open stretches).
- :func:`indoor_route` / :func:`indoor_scene`: a loop of corridors (3-5 m wide) along a
  random convex polygon, doors in their walls, rooms behind some doors, a ceiling
  (ids: 0 floor, 1 ceiling, 10.. corridor walls, 3000.. room walls).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.simulation.scene import Scene, Surface, ground, wall

#: Ids of the special surfaces of the procedural scenes.
GROUND_ID, CEILING_ID, FENCE_ID0, LONE_ID0, ROOM_ID0 = 0, 1, 5000, 6000, 3000


@dataclass(frozen=True)
class Slope:
    """A tilted ground plane ``z = gx x + gy y`` (gradients, m per m)."""

    gx: float = 0.0
    gy: float = 0.0

    def height(self, xy: np.ndarray) -> np.ndarray:
        """Ground height (...,) in metres at points ``xy`` (..., 2)."""
        xy = np.asarray(xy, dtype=np.float64)
        return self.gx * xy[..., 0] + self.gy * xy[..., 1]

    @property
    def normal(self) -> np.ndarray:
        """(3,) unit upward normal of the ground."""
        n = np.array([-self.gx, -self.gy, 1.0])
        return n / np.linalg.norm(n)


def random_route(rng: np.random.Generator, length_m: tuple[float, float] = (110.0, 220.0)):
    """A closed star-shaped route: (W, 2) waypoints, counter-clockwise, about
    ``length_m`` long (a lap of the spline through them)."""
    n = int(rng.integers(6, 10))
    angles = np.sort(2 * np.pi * (np.arange(n) + rng.uniform(-0.25, 0.25, n)) / n)
    radii = rng.uniform(0.65, 1.0, n)
    scale = rng.uniform(*length_m) / _polyline_length(_star(angles, radii))
    return _star(angles, radii) * scale


def _star(angles: np.ndarray, radii: np.ndarray) -> np.ndarray:
    return np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])


def _polyline_length(w: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(np.vstack([w, w[:1]]), axis=0), axis=1).sum())


def route_samples(path_xy: np.ndarray, step: float = 1.0) -> np.ndarray:
    """Points (M, 2) along a closed polyline (K, 2) about ``step`` m apart."""
    w = np.vstack([path_xy, path_xy[:1]])
    out = []
    for a, b in zip(w[:-1], w[1:], strict=True):
        m = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + np.linspace(0.0, 1.0, m, endpoint=False)[:, None] * (b - a))
    return np.concatenate(out)


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances (M,) of points ``p`` (M, 2) to the segment ``a`` -> ``b`` (2,) each."""
    ab = b - a
    s = np.clip((p - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    return np.linalg.norm(p - (a + s[:, None] * ab), axis=1)


def polygon_distance(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distances (M,) in metres of points ``p`` (M, 2) to a convex counter-clockwise
    polygon ``poly`` (K, 2): to its nearest edge, 0 inside."""
    nxt = np.roll(poly, -1, axis=0)
    d = np.min([segment_distance(p, a, b) for a, b in zip(poly, nxt, strict=True)], axis=0)
    e = nxt - poly
    cross = e[None, :, 0] * (p[:, None, 1] - poly[None, :, 1]) - e[None, :, 1] * (
        p[:, None, 0] - poly[None, :, 0]
    )
    return np.where(np.all(cross >= 0, axis=1), 0.0, d)


def _footprint(rng: np.random.Generator, centre: np.ndarray) -> np.ndarray:
    """A random convex footprint (K, 2), counter-clockwise: a rectangle (60 %) or a convex
    polygon of 5-7 vertices on an ellipse, 6-22 m across, at a random yaw."""
    yaw = rng.uniform(0.0, np.pi)
    half = rng.uniform(3.0, 11.0, 2)
    if rng.random() < 0.6:
        local = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=np.float64) * half
    else:
        k = int(rng.integers(5, 8))
        a = np.sort(2 * np.pi * (np.arange(k) + rng.uniform(-0.3, 0.3, k)) / k)
        local = np.column_stack([np.cos(a), np.sin(a)]) * half
    c, s = np.cos(yaw), np.sin(yaw)
    return centre + local @ np.array([[c, s], [-s, c]])


def _walls_of(poly: np.ndarray, first_id: int, bottom: float, top: float, kind="wall"):
    """The vertical walls over the edges of a 2D polygon (K, 2)."""
    nxt = np.roll(poly, -1, axis=0)
    return [
        wall(first_id + i, a, b, bottom, top, kind=kind)
        for i, (a, b) in enumerate(zip(poly, nxt, strict=True))
        if np.linalg.norm(b - a) > 0.5
    ]


def _open_mask(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n,) bool, the route samples of one or two open stretches (each 10-18 % of a lap)."""
    mask = np.zeros(n, dtype=bool)
    for _ in range(int(rng.integers(1, 3))):
        start, length = int(rng.integers(0, n)), int(n * rng.uniform(0.10, 0.18))
        mask[(start + np.arange(length)) % n] = True
    return mask


def outdoor_scene(rng: np.random.Generator, path_xy: np.ndarray, slope: Slope) -> Scene:
    """Buildings, fences and lone walls around the closed path ``path_xy`` (K, 2) (densely
    sampled, e.g. the trajectory's positions) on the ``slope`` (module docstring)."""
    samples = route_samples(path_xy)
    is_open = _open_mask(rng, len(samples))
    lo, hi = samples.min(axis=0) - 35.0, samples.max(axis=0) + 35.0
    surfaces: list[Surface] = []
    footprints: list[tuple[np.ndarray, float]] = []
    next_id = 1
    for _ in range(800):
        if len(footprints) >= 40:
            break
        poly = _footprint(rng, np.zeros(2))
        height, clearance = rng.uniform(6.0, 15.0), rng.uniform(3.5, 8.0)
        near_route = rng.random() < 0.8
        poly += _beside(rng, samples, poly, clearance) if near_route else rng.uniform(lo, hi)
        d = polygon_distance(samples, poly)
        near = d < 18.0
        radius = float(np.max(np.linalg.norm(poly - poly.mean(axis=0), axis=1)))
        if d.min() < clearance or np.any(is_open & near) or _overlaps(poly, radius, footprints):
            continue
        footprints.append((poly, radius))
        z0 = float(slope.height(poly).min()) - 0.5
        surfaces += _walls_of(poly, next_id, z0, z0 + 0.5 + height)
        next_id += len(poly)
    surfaces += _fences(rng, samples, slope)
    surfaces += _lone_walls(rng, samples, is_open, slope)
    return Scene((_sloped_ground(surfaces, slope), *surfaces), "random-outdoor")


def _beside(rng, samples: np.ndarray, poly: np.ndarray, clearance: float) -> np.ndarray:
    """(2,) a centre for the footprint ``poly`` (centred at 0) 0-15 m beyond ``clearance``
    from a random point of the route, on a random side."""
    k = int(rng.integers(0, len(samples)))
    tangent = samples[(k + 1) % len(samples)] - samples[k - 1]
    side = np.array([-tangent[1], tangent[0]]) / np.linalg.norm(tangent) * rng.choice([-1, 1])
    reach = float(np.max(np.abs(poly @ side)))
    return samples[k] + (clearance + reach + rng.uniform(0.0, 15.0)) * side


def _overlaps(poly: np.ndarray, radius: float, others: list[tuple[np.ndarray, float]]) -> bool:
    c = poly.mean(axis=0)
    return any(np.linalg.norm(c - q.mean(axis=0)) < radius + r + 1.0 for q, r in others)


def _fences(rng: np.random.Generator, samples: np.ndarray, slope: Slope) -> list[Surface]:
    """3-8 fences and low walls (0.8-2 m high, 4-20 m long) 3-8 m beside the route, at up to
    30 deg to it, none closer than 2.5 m to the route."""
    out: list[Surface] = []
    for i in range(int(rng.integers(3, 9))):
        k = int(rng.integers(0, len(samples)))
        p0, p1, centre = _beside_route(rng, samples, k, np.pi / 6, (3.0, 8.0), (2.0, 10.0))
        if segment_distance(samples, p0, p1).min() < 2.5:
            continue
        z0 = float(slope.height(np.array([p0, p1])).min()) - 0.3
        top = float(slope.height(centre)) + rng.uniform(0.8, 2.0)
        out.append(wall(FENCE_ID0 + i, p0, p1, z0, top, kind="wall"))
    return out


def _beside_route(
    rng: np.random.Generator,
    samples: np.ndarray,
    k: int,
    max_angle: float,
    distance_m: tuple[float, float],
    half_length_m: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A wall segment beside route sample ``k`` of ``samples`` (K, 2), m: on a random side,
    at most ``max_angle`` (rad) off the route's direction, its centre a random distance
    (m, range) away, a random half length (m, range). Returns its ends and centre (2,)."""
    tangent = samples[(k + 1) % len(samples)] - samples[k - 1]
    tangent /= np.linalg.norm(tangent)
    side = np.array([-tangent[1], tangent[0]]) * rng.choice([-1.0, 1.0])
    a = rng.uniform(-max_angle, max_angle)
    u = np.cos(a) * tangent + np.sin(a) * side
    centre = samples[k] + rng.uniform(*distance_m) * side
    half = rng.uniform(*half_length_m) * u
    return centre - half, centre + half, centre


def _lone_walls(rng, samples: np.ndarray, is_open: np.ndarray, slope: Slope) -> list[Surface]:
    """One or two long walls (15-40 m, 4-10 m high) 6-15 m from each open stretch."""
    out: list[Surface] = []
    idx = np.flatnonzero(is_open)
    if len(idx) == 0:
        return out
    for i in range(int(rng.integers(1, 3))):
        k = int(rng.choice(idx))
        p0, p1, _ = _beside_route(rng, samples, k, np.pi / 9, (6.0, 15.0), (7.5, 20.0))
        if segment_distance(samples, p0, p1).min() < 4.0:
            continue
        z0 = float(slope.height(np.array([p0, p1])).min()) - 0.5
        out.append(wall(LONE_ID0 + i, p0, p1, z0, z0 + 0.5 + rng.uniform(4.0, 10.0)))
    return out


def _sloped_ground(surfaces: list[Surface], slope: Slope, margin: float = 40.0) -> Surface:
    """The ground (id 0): a rectangle around every surface, on the slope."""
    xy = np.concatenate([s.vertices[:, :2] for s in surfaces])
    lo, hi = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    rect = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    verts = np.column_stack([rect, slope.height(rect)])
    return Surface.from_vertices(GROUND_ID, "ground", verts)


# --------------------------------------------------------------------------- indoor


@dataclass(frozen=True)
class IndoorLayout:
    """A loop of corridors: its polygon (K, 2) counter-clockwise, corridor width and
    ceiling height (m)."""

    polygon: np.ndarray
    width: float
    ceiling: float


def indoor_layout(rng: np.random.Generator) -> IndoorLayout:
    """A random convex polygon of 4-6 corners, 60-140 m around, at a random yaw."""
    n = int(rng.integers(4, 7))
    angles = np.sort(2 * np.pi * (np.arange(n) + rng.uniform(-0.15, 0.15, n)) / n)
    radii = rng.uniform(0.85, 1.0, n)
    poly = _star(angles + rng.uniform(0, 2 * np.pi), radii)
    poly *= rng.uniform(60.0, 140.0) / _polyline_length(poly)
    return IndoorLayout(poly, float(rng.uniform(3.0, 5.0)), float(rng.uniform(2.8, 4.0)))


def indoor_route(layout: IndoorLayout, fillet: float = 1.5, step: float = 3.0) -> np.ndarray:
    """Waypoints (W, 2) along the corridors' centre line: each corner replaced by two points
    ``fillet`` m before and after it and one 35 % of the way into the corner, and points
    every ``step`` m along the legs, so that the spline through them stays within the
    corridor."""
    poly, out = layout.polygon, []
    n = len(poly)
    for i in range(n):
        prev, c, nxt = poly[i - 1], poly[i], poly[(i + 1) % n]
        u0 = (c - prev) / np.linalg.norm(c - prev)
        u1 = (nxt - c) / np.linalg.norm(nxt - c)
        a, b = c - fillet * u0, c + fillet * u1
        out += [a, 0.65 * 0.5 * (a + b) + 0.35 * c, b]
        leg = float(np.linalg.norm(nxt - c)) - 2 * fillet
        k = int(leg // step)
        out += [b + (j + 1) * leg / (k + 1) * u1 for j in range(k)]
    return np.array(out)


def clearance(path_xy: np.ndarray, scene: Scene) -> float:
    """Smallest horizontal distance (m) from the path (M, 2) to a wall or facade."""
    return min(
        float(segment_distance(path_xy, s.vertices[0, :2], s.vertices[1, :2]).min())
        for s in scene.surfaces
        if s.kind in ("wall", "facade")
    )


def _split(a: np.ndarray, b: np.ndarray, doors: list[float], width: float):
    """Pieces of the segment a -> b with door gaps of ``width`` m centred at the fractions
    ``doors`` of its length."""
    length = float(np.linalg.norm(b - a))
    u, cuts, pieces, s0 = (b - a) / length, sorted(doors), [], 0.0
    for f in cuts:
        s1 = f * length - width / 2
        if s1 - s0 > 0.5:
            pieces.append((a + s0 * u, a + s1 * u))
        s0 = f * length + width / 2
    if length - s0 > 0.5:
        pieces.append((a + s0 * u, b))
    return pieces


def indoor_scene(rng: np.random.Generator, layout: IndoorLayout) -> Scene:
    """Corridor walls with doors, rooms behind some doors, floor (id 0) and ceiling (id 1)."""
    poly, w = layout.polygon, layout.width
    surfaces: list[Surface] = []
    room_id, next_id = ROOM_ID0, 10
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        u = (b - a) / np.linalg.norm(b - a)
        right = np.array([u[1], -u[0]])  # outside of a counter-clockwise loop
        for offset, trim in ((w / 2, -w / 2), (-w / 2, w / 2)):
            p0, p1 = a + trim * u + offset * right, b - trim * u + offset * right
            length = float(np.linalg.norm(p1 - p0))
            doors = list(rng.uniform(0.15, 0.85, int(rng.integers(0, 3)))) if length > 8 else []
            for q0, q1 in _split(p0, p1, doors, rng.uniform(1.0, 1.6)):
                surfaces.append(wall(next_id, q0, q1, 0.0, layout.ceiling, kind="wall"))
                next_id += 1
            for f in doors if offset > 0 else []:
                if rng.random() < 0.6:
                    door = p0 + f * length * u
                    surfaces += _room(rng, door, u, right, room_id, layout.ceiling)
                    room_id += 3
    floor = _ground_of(surfaces, margin=2.0)
    verts = floor.vertices.copy()
    verts[:, 2] = layout.ceiling
    ceiling = Surface.from_vertices(CEILING_ID, "polygon", verts[::-1])  # normal down
    return Scene((floor, ceiling, *surfaces), "random-indoor")


def _room(rng, door: np.ndarray, u: np.ndarray, out: np.ndarray, first_id: int, top: float):
    """Three walls of a room (3-7 m wide, 3-6 m deep) behind a door at ``door`` (2,)."""
    half, depth = rng.uniform(1.5, 3.5), rng.uniform(3.0, 6.0)
    c0, c1 = door - half * u, door + half * u
    return [
        wall(first_id, c0, c0 + depth * out, 0.0, top),
        wall(first_id + 1, c0 + depth * out, c1 + depth * out, 0.0, top),
        wall(first_id + 2, c1 + depth * out, c1, 0.0, top),
    ]


def _ground_of(surfaces: list[Surface], margin: float) -> Surface:
    xy = np.concatenate([s.vertices[:, :2] for s in surfaces])
    lo, hi = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    return ground(GROUND_ID, [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
