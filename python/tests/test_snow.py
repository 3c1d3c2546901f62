"""Snow on geometry held in memory: it lies on top of a cube over a plane and equals
``phenomena export snow-mesh`` of the scene it reports."""

import numpy as np

import phenomena
from phenomena._ply import read_ply


def cube_over_plane():
    plane = [[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]]
    lo, hi = np.array([-0.5, 0.0, -0.5]), np.array([0.5, 1.0, 0.5])
    corners = [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    vertices = np.array(plane + corners, dtype=np.float32)
    # Corner k of the cube is vertex 4 + (x·4 + y·2 + z); faces wound outwards.
    c = lambda x, y, z: 4 + x * 4 + y * 2 + z  # noqa: E731
    quads = [
        (c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)),  # top
        (c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)),  # bottom
        (c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)),  # -x
        (c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)),  # +x
        (c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)),  # -z
        (c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)),  # +z
    ]
    triangles = [[0, 2, 1], [0, 3, 2]]
    for a, b, cc, d in quads:
        triangles += [[a, b, cc], [a, cc, d]]
    objects = [0, 0] + [1] * 12
    return vertices, np.array(triangles), objects


def test_snow_lies_on_the_cube_and_the_plane():
    vertices, triangles, objects = cube_over_plane()
    cover = phenomena.snow_cover(vertices, triangles, objects, depth_cm=5.0, snow={"map_resolution": 96})
    assert cover.steps == 25 and cover.hours == 2.5
    p = cover.positions
    on_top = p[(np.abs(p[:, 0]) < 0.4) & (np.abs(p[:, 2]) < 0.4)]
    # 5 cm fell: on the cube's top the snow's surface is 5 cm over y = 1 (within a
    # texel's slope of 4 m / 96), and the plane's is 5 cm over y = 0 away from it.
    assert abs(on_top[:, 1].max() - 1.05) < 0.01
    far = p[np.abs(p[:, 0]) > 1.2]
    assert abs(far[:, 1].max() - 0.05) < 0.01
    # Nothing under the cube's top but the plane's snow (no snow floats in the cube).
    inside = p[(np.abs(p[:, 0]) < 0.45) & (np.abs(p[:, 2]) < 0.45)]
    assert not np.any((inside[:, 1] > 0.06) & (inside[:, 1] < 0.99))


def test_the_snow_equals_the_commands_export_of_its_scene(cli, tmp_path):
    vertices, triangles, objects = cube_over_plane()
    cover = phenomena.snow_cover(vertices, triangles, objects, hours=1.0,
                                 snow={"repose_deg": 40.0, "main_tilt_deg": [20.0, 0.0], "map_resolution": 64})
    (tmp_path / "geometry.obj").write_bytes(cover.geometry_obj)
    (tmp_path / "snow.toml").write_text(cover.scene_toml)
    cli("export", "snow-mesh", tmp_path / "snow.toml", "--format", "ply", "--time-h", cover.hours,
        "--out", tmp_path / "snow.ply")
    ply = read_ply((tmp_path / "snow.ply").read_bytes())
    v = ply["vertex"]
    np.testing.assert_array_equal(cover.positions, np.stack([v["x"], v["y"], v["z"]], axis=1))
    np.testing.assert_array_equal(cover.normals, np.stack([v["nx"], v["ny"], v["nz"]], axis=1))
    np.testing.assert_array_equal(cover.triangles, ply["face"]["vertex_indices"])
    assert len(cover.triangles) > 100


def test_bad_geometry_and_values_are_refused():
    vertices, triangles, objects = cube_over_plane()
    import pytest

    with pytest.raises(ValueError, match="triangles index vertices"):
        phenomena.snow_cover(vertices, triangles + 100)
    with pytest.raises(phenomena.SceneError, match="repose_deg"):
        phenomena.snow_cover(vertices, triangles, snow={"repose_deg": 95.0})
    with pytest.raises(ValueError, match="hours"):
        phenomena.snow_cover(vertices, triangles, hours=-1.0)
