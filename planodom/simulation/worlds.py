"""Built-in scenes: the paper's loop, an urban canyon and random walls.

Every built-in is deterministic (procedural, with a fixed seed where random). World frame:
z up, the ground at ``z = 0``; routes are given as 2D waypoints (x, y), metres, that the
matching trajectories in :mod:`planodom.simulation.trajectory` follow.
"""

from __future__ import annotations

import numpy as np

from planodom.errors import ConfigError
from planodom.simulation.scene import Scene, Surface, ground, wall

#: Closed route of the paper loop (like the paper's Fig. 4): (W, 2) waypoints, metres,
#: counter-clockwise, about 50 m x 36 m; legs at 0, 40, 80, 140, 180, 207, 256, 315 deg.
PAPER_LOOP_ROUTE = np.array(
    [[0, 0], [28, 0], [40, 10], [42, 26], [30, 36], [12, 36], [-4, 28], [-8, 12]],
    dtype=np.float64,
)

#: Per leg of the paper loop: (outer offset, inner offset, outer top, inner top, split outer)
#: with offsets in metres from the route, heights in metres.
_LOOP_LEGS = [
    (9.0, 7.0, 8.0, 5.0, True),
    (8.0, 6.0, 6.0, 10.0, False),
    (10.0, 7.0, 12.0, 6.0, True),
    (7.0, 6.5, 5.0, 8.0, False),
    (9.0, 7.0, 9.0, 5.0, True),
    (8.0, 6.0, 7.0, 9.0, False),
    (11.0, 7.0, 10.0, 6.0, False),
    (8.0, 6.0, 6.0, 7.0, True),
]

#: Extra free-standing walls (start, end, top), at 20-70 degrees to the route legs.
_LOOP_EXTRA = [
    ((8.0, 12.0), (14.0, 20.0), 4.0),  # inside the block, 53 deg
    ((24.0, 12.0), (30.0, 16.0), 5.0),  # 34 deg
    ((20.0, 24.0), (24.0, 30.0), 3.5),  # 56 deg
    ((-20.0, -6.0), (-12.0, -16.0), 7.0),  # outside, -51 deg
    ((50.0, -4.0), (56.0, 8.0), 6.0),  # 63 deg
    ((46.0, 40.0), (56.0, 36.0), 8.0),  # -22 deg
    ((-16.0, 40.0), (-8.0, 46.0), 6.0),  # 37 deg
]


def _offset_segment(a: np.ndarray, b: np.ndarray, offset: float, trim: float) -> np.ndarray:
    """(2, 2) segment parallel to a -> b, moved ``offset`` m to its right, trimmed at both ends."""
    u = (b - a) / np.linalg.norm(b - a)
    right = np.array([u[1], -u[0]])
    return np.array([a + trim * u, b - trim * u]) + offset * right


def _leg_walls(a, b, spec, first_id: int) -> list[Surface]:
    d_out, d_in, top_out, top_in, split = spec
    out = _offset_segment(a, b, d_out, -2.0)  # outer walls overhang the corners
    trim = min(d_in + 1.0, 0.3 * float(np.linalg.norm(b - a)))
    inner = _offset_segment(a, b, -d_in, trim)  # inner walls stop short of the corners
    walls = []
    if split:  # an alley across the middle of the outer wall
        mid = out.mean(axis=0)
        u = (out[1] - out[0]) / np.linalg.norm(out[1] - out[0])
        walls += [
            wall(first_id, out[0], mid - 2.0 * u, 0.0, top_out),
            wall(first_id + 1, mid + 2.0 * u, out[1], 0.0, top_out + 2.0),
        ]
    else:
        walls.append(wall(first_id, out[0], out[1], 0.0, top_out))
    walls.append(wall(first_id + 2, inner[0], inner[1], 0.0, top_in, kind="facade"))
    return walls


def _ground_around(surfaces: list[Surface], margin: float, id: int = 0) -> Surface:
    xy = np.concatenate([s.vertices[:, :2] for s in surfaces])
    lo, hi = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    return ground(id, [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]], 0.0)


def paper_loop() -> Scene:
    """The paper's test scene (Fig. 4): walls of many orientations around a closed loop.

    Outer walls (some split by alleys) and inner facades follow the 8 legs of
    :data:`PAPER_LOOP_ROUTE` at 6-11 m, with gaps at the corners where beams escape to
    infinity; 7 free-standing walls at 20-70 degrees to the legs; a ground rectangle
    (id 0) at z = 0. Wall ids: 10 * leg + 1..3 along the legs, 100 + i for the extras.
    """
    route = PAPER_LOOP_ROUTE
    surfaces: list[Surface] = []
    for i, spec in enumerate(_LOOP_LEGS):
        a, b = route[i], route[(i + 1) % len(route)]
        surfaces += _leg_walls(a, b, spec, 10 * (i + 1) + 1)
    for i, (p0, p1, top) in enumerate(_LOOP_EXTRA):
        surfaces.append(wall(100 + i, p0, p1, 0.0, top))
    return Scene((_ground_around(surfaces, 12.0), *surfaces), "paper-loop")


#: Route of the urban canyon: (W, 2) waypoints, metres, along the street's centre line.
URBAN_CANYON_ROUTE = np.array(
    [[0, 0], [30, 0.8], [60, -0.6], [90, 0.5], [120, -0.8], [150, 0]], dtype=np.float64
)
_CROSS_STREETS = ((45.0, 57.0), (100.0, 112.0))  # x ranges, metres


def _facade_row(rng: np.random.Generator, side: float, first_id: int) -> list[Surface]:
    """Facade segments along one side (side = +1 left, -1 right) of the street."""
    walls, x, k = [], -10.0, first_id
    while x < 160.0:
        length = rng.uniform(8.0, 20.0)
        x1 = min(x + length, 170.0)
        gap = next(((a, b) for a, b in _CROSS_STREETS if a < x1 and b > x), None)
        if gap is not None:  # stop at the cross street, resume after it
            x1 = gap[0]
        if x1 - x > 2.0:
            setback = rng.uniform(6.0, 10.0)
            skew = np.deg2rad(rng.uniform(-8.0, 8.0)) * (x1 - x) / 2.0
            y0, y1 = side * (setback - skew), side * (setback + skew)
            top = rng.uniform(8.0, 20.0)
            walls.append(wall(k, (x, y0), (x1, y1), 0.0, top, kind="facade"))
            k += 1
        x = (gap[1] if gap is not None else x1) + rng.uniform(0.0, 3.0) * (rng.random() < 0.3)
    return walls


def urban_canyon(seed: int = 7) -> Scene:
    """A 150 m street along +x with facades on both sides (setbacks 6-10 m, skews up to
    8 deg, heights 8-20 m), two 12 m wide cross streets lined with walls, and the ground
    (id 0). Ids: 1000+ left facades, 2000+ right facades, 3000+ cross-street walls."""
    rng = np.random.default_rng(seed)
    surfaces = _facade_row(rng, 1.0, 1000) + _facade_row(rng, -1.0, 2000)
    k = 3000
    for xa, xb in _CROSS_STREETS:
        for side in (1.0, -1.0):
            for x in (xa, xb):
                top = rng.uniform(8.0, 16.0)
                surfaces.append(wall(k, (x, side * 9.0), (x, side * 45.0), 0.0, top))
                k += 1
    return Scene((_ground_around(surfaces, 15.0), *surfaces), "urban-canyon")


def random_walls(n: int = 100, extent: float = 60.0, seed: int = 0) -> Scene:
    """``n`` random vertical walls (3-15 m long, 3-12 m tall) in a square of side
    ``extent`` (m) centred on the origin, plus the ground (id 0); walls have ids 1..n."""
    rng = np.random.default_rng(seed)
    c = rng.uniform(-extent / 2, extent / 2, (n, 2))
    a = rng.uniform(0.0, np.pi, n)
    half = rng.uniform(1.5, 7.5, n)[:, None] * np.column_stack([np.cos(a), np.sin(a)])
    tops = rng.uniform(3.0, 12.0, n)
    surfaces = [wall(i + 1, c[i] - half[i], c[i] + half[i], 0.0, tops[i]) for i in range(n)]
    return Scene((_ground_around(surfaces, 10.0), *surfaces), f"random-walls-{n}")


SCENES = {"paper-loop": paper_loop, "urban-canyon": urban_canyon}


def scene_from_name(name: str) -> Scene:
    """A built-in scene by name: ``"paper-loop"`` or ``"urban-canyon"``."""
    if name not in SCENES:
        raise ConfigError(f"unknown scene '{name}' (choose from {', '.join(SCENES)})")
    return SCENES[name]()
