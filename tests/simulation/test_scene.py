"""Scenes: surfaces and their planes, built-in scenes, the YAML format and its errors."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from planodom.errors import DatasetError, GeometryError
from planodom.simulation import (
    PAPER_LOOP_ROUTE,
    Scene,
    Surface,
    ground,
    load_scene,
    paper_loop,
    random_walls,
    save_scene,
    scene_from_dict,
    scene_to_dict,
    urban_canyon,
    wall,
)

coord = st.floats(-100, 100, allow_nan=False)


@given(coord, coord, coord, coord, st.floats(-2, 2), st.floats(0.5, 20))
def test_wall_plane_contains_its_vertices(x0, y0, x1, y1, bottom, height):
    if np.hypot(x1 - x0, y1 - y0) < 0.1:
        return
    w = wall(3, (x0, y0), (x1, y1), bottom, bottom + height)
    assert w.vertices.shape == (4, 3) and w.vertices.dtype == np.float64
    assert np.linalg.norm(w.normal) == pytest.approx(1.0)
    assert w.normal[2] == pytest.approx(0.0, abs=1e-12)
    assert np.abs(w.distance(w.vertices)).max() < 1e-9
    assert w.area == pytest.approx(np.hypot(x1 - x0, y1 - y0) * height, rel=1e-9)


def test_ground_normal_points_up_whatever_the_winding():
    square = [[0, 0], [10, 0], [10, 10], [0, 10]]
    for poly in (square, square[::-1]):
        g = ground(0, poly, z=-0.5)
        np.testing.assert_allclose(g.normal, [0, 0, 1], atol=1e-15)
        assert g.offset == pytest.approx(0.5)


def test_bad_polygons_are_rejected():
    with pytest.raises(GeometryError, match="coplanar"):
        Surface.from_vertices(1, "polygon", [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 1]])
    with pytest.raises(GeometryError, match="convex"):
        ground(1, [[0, 0], [4, 0], [1, 1], [0, 4]])
    with pytest.raises(GeometryError, match="top"):
        wall(1, (0, 0), (1, 0), bottom=2.0, top=1.0)
    with pytest.raises(GeometryError, match="unique"):
        Scene((wall(1, (0, 0), (1, 0)), wall(1, (0, 1), (1, 1))))


def test_triangles_lie_on_their_surfaces():
    scene = paper_loop()
    verts, tris, owner = scene.triangles()
    assert len(tris) == sum(len(s.vertices) - 2 for s in scene.surfaces)
    for k, s in enumerate(scene.surfaces):
        pts = verts[tris[owner == k].ravel()]
        assert np.abs(s.distance(pts)).max() < 1e-9


def _wall_azimuths(scene: Scene) -> np.ndarray:
    walls = [s for s in scene.surfaces if s.kind != "ground"]
    return np.rad2deg(np.arctan2([s.normal[1] for s in walls], [s.normal[0] for s in walls]))


def test_paper_loop_is_like_fig4():
    scene = paper_loop()
    extent = PAPER_LOOP_ROUTE.max(axis=0) - PAPER_LOOP_ROUTE.min(axis=0)
    assert 40 <= extent.max() <= 60
    assert sum(s.kind == "ground" for s in scene.surfaces) == 1
    # not only Manhattan: several walls at 20-70 degrees off the axes
    off_axis = np.mod(_wall_azimuths(scene), 90.0)
    assert np.count_nonzero((off_axis > 20) & (off_axis < 70)) >= 6
    assert len(np.unique(np.round(np.mod(_wall_azimuths(scene), 180)))) >= 8


def test_urban_canyon_is_a_long_street():
    scene = urban_canyon()
    xy = np.concatenate([s.vertices[:, :2] for s in scene.surfaces if s.kind != "ground"])
    assert xy[:, 0].max() - xy[:, 0].min() >= 150
    left = [s for s in scene.surfaces if 1000 <= s.id < 2000]
    right = [s for s in scene.surfaces if 2000 <= s.id < 3000]
    assert len(left) >= 5 and len(right) >= 5
    assert all(s.vertices[:, 1].min() > 3 for s in left)
    assert all(s.vertices[:, 1].max() < -3 for s in right)


@pytest.mark.parametrize("make", [paper_loop, urban_canyon, lambda: random_walls(30, seed=4)])
def test_yaml_round_trip_is_exact(tmp_path, make):
    scene = make()
    path = tmp_path / "scene.yaml"
    save_scene(scene, path)
    back = load_scene(path)
    assert back.name == scene.name and len(back) == len(scene)
    for a, b in zip(scene.surfaces, back.surfaces, strict=True):
        assert (a.id, a.kind) == (b.id, b.kind)
        np.testing.assert_array_equal(a.vertices, b.vertices)
        np.testing.assert_array_equal(a.normal, b.normal)
        assert a.offset == b.offset


def test_generic_polygon_round_trips():
    tri = Surface.from_vertices(9, "polygon", [[0, 0, 0], [1, 0, 0], [1, 1, 1]])
    back = scene_from_dict(scene_to_dict(Scene((tri,))))
    np.testing.assert_array_equal(back.surfaces[0].vertices, tri.vertices)


GOOD = {
    "name": "t",
    "surfaces": [{"id": 1, "kind": "wall", "start": [0, 0], "end": [5, 0], "top": 3.0}],
}


@pytest.mark.parametrize(
    ("mutate", "field"),
    [
        (lambda d: d["surfaces"][0].pop("top"), "surfaces.0.wall.top"),
        (lambda d: d["surfaces"][0].update(start=[0, 0, 0]), "surfaces.0.wall.start"),
        (lambda d: d["surfaces"][0].update(top=-1.0), "surfaces.0.wall"),
        (lambda d: d["surfaces"][0].update(kind="roof"), "surfaces.0"),
        (lambda d: d["surfaces"][0].update(colour="red"), "surfaces.0.wall.colour"),
        (lambda d: d.update(surfaces=[]), "surfaces"),
        (lambda d: d["surfaces"].append(dict(d["surfaces"][0])), "surfaces"),
        # true / false were read as 1 / 0
        (lambda d: d["surfaces"][0].update(top=True), "surfaces.0.wall': Value error, 'top"),
        (lambda d: d["surfaces"][0].update(id=False), "surfaces.0.wall': Value error, 'id"),
        (lambda d: d["surfaces"][0].update(end=[5, True]), "surfaces.0.wall': Value error, 'end"),
    ],
)
def test_bad_scene_file_names_file_and_field(tmp_path, mutate, field):
    data = yaml.safe_load(yaml.safe_dump(GOOD))
    mutate(data)
    path = tmp_path / "bad_scene.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(DatasetError) as info:
        load_scene(path)
    assert str(path) in str(info.value) and f"'{field}" in str(info.value)


def test_unreadable_scene_files(tmp_path):
    with pytest.raises(DatasetError, match="missing.yaml"):
        load_scene(tmp_path / "missing.yaml")
    path = tmp_path / "broken.yaml"
    path.write_text("surfaces: [unclosed")
    with pytest.raises(DatasetError, match="broken.yaml.*YAML"):
        load_scene(path)
    path.write_text(yaml.safe_dump(GOOD))
    assert load_scene(path).surfaces[0].id == 1
