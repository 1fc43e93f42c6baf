"""Scenes of finite planar polygons (walls, facades, ground) and their YAML file format.

A :class:`Surface` is a convex planar polygon ``(M, 3)`` (float64, metres, world frame)
with an integer id, a kind and its plane ``n . p + d = 0`` (float64). Walls and facades
are vertical rectangles given by two 2D endpoints and a bottom and top height; their
normal is the left normal of ``end - start`` (``(-dy, dx, 0) / |.|``), which is arbitrary:
the simulator does not care which side a surface is seen from. The ground is a
horizontal polygon with normal ``+z``.

Scene file (YAML), every length in metres::

    name: paper-loop            # optional, free text
    surfaces:                   # list, at least one entry; ids unique integers
      - id: 1
        kind: wall              # wall | facade: vertical rectangle
        start: [0.0, -8.0]      # 2D endpoint (x, y)
        end: [30.0, -8.0]       # 2D endpoint (x, y), distinct from start
        bottom: 0.0             # height of the lower edge
        top: 6.0                # height of the upper edge, > bottom
      - id: 0
        kind: ground            # horizontal convex polygon
        polygon: [[-50, -50], [90, -50], [90, 70], [-50, 70]]   # >= 3 (x, y) vertices
        z: 0.0                  # height of the polygon
      - id: 9
        kind: polygon           # any convex planar polygon
        vertices: [[0, 0, 0], [1, 0, 0], [1, 1, 1]]   # >= 3 (x, y, z), coplanar

Unknown keys and malformed values raise :class:`planodom.errors.DatasetError` naming the
file and the field (for example ``scene.yaml: surfaces.3.top: ...``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from planodom.config.section import admits_bool, holds_bool
from planodom.errors import DatasetError, GeometryError
from planodom.yaml_files import read_yaml_file

Kind = Literal["wall", "facade", "ground", "polygon"]
VERTICAL_KINDS = ("wall", "facade")
_PLANARITY_TOL = 1e-6  # metres


@dataclass(frozen=True, eq=False)
class Surface:
    """One finite planar polygon of a scene.

    Attributes:
        id: integer id; simulated points carry it as their ``label``.
        kind: ``"wall"``, ``"facade"``, ``"ground"`` or ``"polygon"``.
        vertices: (M, 3) float64, metres, convex polygon in order, M >= 3.
        normal: (3,) float64 unit normal. offset: ``d`` (m) with ``n . p + d = 0``.
    """

    id: int
    kind: str
    vertices: np.ndarray
    normal: np.ndarray
    offset: float

    @classmethod
    def from_vertices(cls, id: int, kind: str, vertices: np.ndarray) -> Surface:
        """Surface from (M, 3) vertices; the normal follows their winding (right hand)."""
        v = np.asarray(vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3 or not np.all(np.isfinite(v)):
            raise GeometryError(f"surface {id}: need (M >= 3, 3) finite vertices")
        c = v.mean(axis=0)
        # Newell's normal: robust for any planar polygon, follows the winding.
        area_vec = 0.5 * np.cross(v - c, np.roll(v, -1, axis=0) - c).sum(axis=0)
        norm = np.linalg.norm(area_vec)
        if norm < 1e-9:
            raise GeometryError(f"surface {id}: degenerate polygon (zero area)")
        n = area_vec / norm
        d = float(-n @ c)
        if np.max(np.abs(v @ n + d)) > _PLANARITY_TOL:
            raise GeometryError(f"surface {id}: vertices are not coplanar")
        edges = np.roll(v, -1, axis=0) - v
        if np.any(np.cross(edges, np.roll(edges, -1, axis=0)) @ n < -1e-9):
            raise GeometryError(f"surface {id}: polygon is not convex")
        return cls(int(id), kind, v, n, d)

    @property
    def area(self) -> float:
        """Area of the polygon, m^2."""
        c = self.vertices.mean(axis=0)
        cr = np.cross(self.vertices - c, np.roll(self.vertices, -1, axis=0) - c)
        return float(0.5 * np.linalg.norm(cr.sum(axis=0)))

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distances (N,), metres, of world points (N, 3) to this surface's plane."""
        return np.asarray(points) @ self.normal + self.offset


def wall(id: int, start, end, bottom: float = 0.0, top: float = 6.0, kind: str = "wall") -> Surface:
    """Vertical rectangle over the 2D segment ``start`` -> ``end`` (2,) each, metres, from
    height ``bottom`` to ``top`` (m)."""
    p0 = np.asarray(start, dtype=np.float64).reshape(2)
    p1 = np.asarray(end, dtype=np.float64).reshape(2)
    if not top > bottom:
        raise GeometryError(f"wall {id}: top {top} must exceed bottom {bottom}")
    verts = np.array(
        [[*p0, bottom], [*p1, bottom], [*p1, top], [*p0, top]],
        dtype=np.float64,
    )
    return Surface.from_vertices(id, kind, verts)


def ground(id: int, polygon, z: float = 0.0) -> Surface:
    """Horizontal polygon at height ``z`` (m) from (M, 2) ``polygon`` vertices; normal +z."""
    xy = np.asarray(polygon, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise GeometryError(f"ground {id}: polygon must be (M, 2)")
    signed = 0.5 * np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1])
    if signed < 0:
        xy = xy[::-1]  # counter-clockwise seen from above: normal +z
    verts = np.column_stack([xy, np.full(len(xy), float(z))])
    return Surface.from_vertices(id, "ground", verts)


@dataclass(frozen=True, eq=False)
class Scene:
    """A named set of surfaces with unique ids."""

    surfaces: tuple[Surface, ...]
    name: str = "scene"

    def __post_init__(self) -> None:
        object.__setattr__(self, "surfaces", tuple(self.surfaces))
        ids = [s.id for s in self.surfaces]
        if len(set(ids)) != len(ids):
            raise GeometryError(f"scene '{self.name}': surface ids are not unique")

    def __len__(self) -> int:
        return len(self.surfaces)

    @property
    def ids(self) -> np.ndarray:
        """(K,) int64 surface ids."""
        return np.array([s.id for s in self.surfaces], dtype=np.int64)

    @property
    def normals(self) -> np.ndarray:
        """(K, 3) float64 unit normals."""
        return np.array([s.normal for s in self.surfaces]).reshape(-1, 3)

    @property
    def offsets(self) -> np.ndarray:
        """(K,) float64 plane offsets, metres."""
        return np.array([s.offset for s in self.surfaces], dtype=np.float64)

    def by_id(self, id: int) -> Surface:
        """The surface with this id (raises KeyError)."""
        for s in self.surfaces:
            if s.id == id:
                return s
        raise KeyError(id)

    def triangles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fan triangulation: vertices (V, 3) float64, triangles (F, 3) int64 and the index
        (F,) into :attr:`surfaces` of each triangle's surface."""
        verts, tris, owner, base = [], [], [], 0
        for k, s in enumerate(self.surfaces):
            m = len(s.vertices)
            j = np.arange(1, m - 1)
            tris.append(np.column_stack([np.zeros_like(j), j, j + 1]) + base)
            owner.append(np.full(m - 2, k))
            verts.append(s.vertices)
            base += m
        return np.concatenate(verts), np.concatenate(tris), np.concatenate(owner)


# --------------------------------------------------------------------------- YAML


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    id: int

    @model_validator(mode="before")
    @classmethod
    def _no_bool_for_numbers(cls, data: Any) -> Any:
        """Refuse ``true`` / ``false`` for a number (pydantic would read 1 / 0)."""
        if isinstance(data, dict):
            for name, value in data.items():
                known = cls.model_fields.get(name)
                if known is not None and holds_bool(value) and not admits_bool(known.annotation):
                    raise ValueError(f"'{name}' expects numbers, not a boolean ({value!r})")
        return data


class _WallSpec(_Spec):
    kind: Literal["wall", "facade"]
    start: Annotated[list[float], Field(min_length=2, max_length=2)]
    end: Annotated[list[float], Field(min_length=2, max_length=2)]
    bottom: float = 0.0
    top: float

    @model_validator(mode="after")
    def _check(self) -> _WallSpec:
        if self.top <= self.bottom:
            raise ValueError(f"top ({self.top}) must exceed bottom ({self.bottom})")
        if np.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1]) < 1e-6:
            raise ValueError("start and end coincide")
        return self


class _GroundSpec(_Spec):
    kind: Literal["ground"]
    polygon: Annotated[
        list[Annotated[list[float], Field(min_length=2, max_length=2)]], Field(min_length=3)
    ]
    z: float = 0.0


class _PolygonSpec(_Spec):
    kind: Literal["polygon"]
    vertices: Annotated[
        list[Annotated[list[float], Field(min_length=3, max_length=3)]], Field(min_length=3)
    ]


class _SceneSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str = "scene"
    surfaces: Annotated[
        list[Annotated[_WallSpec | _GroundSpec | _PolygonSpec, Field(discriminator="kind")]],
        Field(min_length=1),
    ]


def surface_to_dict(s: Surface) -> dict:
    """The YAML entry of a surface (see the module docstring)."""
    v = s.vertices
    rect = len(v) == 4 and np.array_equal(v[0, :2], v[3, :2]) and np.array_equal(v[1, :2], v[2, :2])
    if s.kind in VERTICAL_KINDS and rect and v[0, 2] == v[1, 2] and v[2, 2] == v[3, 2]:
        return {
            "id": s.id,
            "kind": s.kind,
            "start": v[0, :2].tolist(),
            "end": v[1, :2].tolist(),
            "bottom": float(v[0, 2]),
            "top": float(v[2, 2]),
        }
    if s.kind == "ground" and np.all(v[:, 2] == v[0, 2]):
        return {"id": s.id, "kind": "ground", "polygon": v[:, :2].tolist(), "z": float(v[0, 2])}
    return {"id": s.id, "kind": "polygon", "vertices": v.tolist()}


def scene_to_dict(scene: Scene) -> dict:
    """The YAML document of a scene (plain lists and floats)."""
    return {"name": scene.name, "surfaces": [surface_to_dict(s) for s in scene.surfaces]}


def scene_from_dict(data: object, source: str = "scene") -> Scene:
    """Validate a scene document; errors are :class:`DatasetError` naming ``source`` and field."""
    try:
        spec = _SceneSpec.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        loc = ".".join(str(x) for x in first["loc"]) or "(document)"
        raise DatasetError(f"{source}: field '{loc}': {first['msg']}") from exc
    surfaces = []
    for i, e in enumerate(spec.surfaces):
        try:
            if isinstance(e, _WallSpec):
                surfaces.append(wall(e.id, e.start, e.end, e.bottom, e.top, kind=e.kind))
            elif isinstance(e, _GroundSpec):
                surfaces.append(ground(e.id, e.polygon, e.z))
            else:
                surfaces.append(Surface.from_vertices(e.id, "polygon", np.array(e.vertices)))
        except GeometryError as exc:
            raise DatasetError(f"{source}: field 'surfaces.{i}': {exc}") from exc
    try:
        return Scene(tuple(surfaces), spec.name)
    except GeometryError as exc:
        raise DatasetError(f"{source}: field 'surfaces': {exc}") from exc


def save_scene(scene: Scene, path: str | Path) -> None:
    """Write ``scene`` as YAML to ``path``."""
    Path(path).write_text(yaml.safe_dump(scene_to_dict(scene), sort_keys=False))


def load_scene(path: str | Path) -> Scene:
    """Read a scene YAML file; raises :class:`DatasetError` naming the file and field."""
    path = Path(path)
    data = read_yaml_file(path, "scene", DatasetError)
    return scene_from_dict(data, source=str(path))
