"""Mesh triangulation, normals, primvars and implicit-shape tessellation."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd
from stagegen import usda_stage

from stb_hydra.scene.geometry import read_mesh_geometry, triangulate


def mesh(body: str, type_: str = "Mesh"):
    st = usda_stage(f'#usda 1.0\ndef {type_} "M"\n{{\n{body}\n}}\n')
    return read_mesh_geometry(st.GetPrimAtPath("/M"), Usd.TimeCode.Default())


def tri_normals(g) -> np.ndarray:
    p = g.points[g.indices.astype(int)]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)


def test_fan_triangulation_counts_and_holes():
    corners, face = triangulate(np.array([3, 4, 5, 2]), np.arange(14), holes=np.array([1]))
    # triangle 1, (quad is a hole), pentagon 3, degenerate 2-gon 0
    assert len(corners) == 4
    assert face.tolist() == [0, 2, 2, 2]
    assert corners[1].tolist() == [7, 8, 9]


QUAD = """int[] faceVertexCounts = [4]
int[] faceVertexIndices = [0, 1, 2, 3]
point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]"""


def test_winding_and_left_handed_orientation():
    g = mesh(QUAD)
    assert np.allclose(tri_normals(g), [0, 0, 1])
    assert np.allclose(g.normals, [0, 0, 1], atol=1e-6)
    g = mesh(QUAD + '\nuniform token orientation = "leftHanded"')
    assert np.allclose(tri_normals(g), [0, 0, -1])


def test_authored_normals_all_interpolations():
    g = mesh(
        QUAD + "\nnormal3f[] normals = [(0, 0, 1), (0, 0, 1), (0, 0, 1), (0, 0, 1)] (\n"
        'interpolation = "vertex"\n)'
    )
    assert len(g.points) == 4 and np.allclose(g.normals, [0, 0, 1])
    g = mesh(QUAD + '\nnormal3f[] primvars:normals = [(0, 1, 0)] (\ninterpolation = "uniform"\n)')
    assert np.allclose(g.normals, [0, 1, 0])
    g = mesh(
        QUAD + "\nnormal3f[] normals = [(1, 0, 0), (1, 0, 0), (0, 1, 0), (0, 1, 0)] (\n"
        'interpolation = "faceVarying"\n)'
    )
    assert len(g.points) == 4
    assert sorted(map(tuple, np.round(g.normals, 3).tolist())) == [
        (0.0, 1.0, 0.0),
        (0.0, 1.0, 0.0),
        (1.0, 0.0, 0.0),
        (1.0, 0.0, 0.0),
    ]


def test_wrong_sized_normals_are_recomputed_with_a_warning():
    g = mesh(QUAD + '\nnormal3f[] normals = [(0, 0, 1)] (\ninterpolation = "vertex"\n)')
    assert np.allclose(g.normals, [0, 0, 1], atol=1e-6)
    assert any("wrong size" in w for w in g.warnings)


CUBE_8 = """int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]
int[] faceVertexIndices = [0, 1, 3, 2, 4, 6, 7, 5, 0, 4, 5, 1, 2, 3, 7, 6, 0, 2, 6, 4, 1, 5, 7, 3]
point3f[] points = [(-1, -1, -1), (1, -1, -1), (-1, 1, -1), (1, 1, -1),
    (-1, -1, 1), (1, -1, 1), (-1, 1, 1), (1, 1, 1)]"""


def test_computed_normals_keep_hard_edges():
    g = mesh(CUBE_8)
    # 8 shared points, 6 faces: faceted normals need 24 corners, each axis-aligned
    assert len(g.points) == 24
    ax = np.abs(g.normals).max(axis=1)
    assert np.allclose(ax, 1.0, atol=1e-6)
    # every corner normal equals its triangle's normal
    tn = tri_normals(g)
    for k in range(3):
        assert np.allclose(g.normals[g.indices[:, k].astype(int)], tn, atol=1e-6)


def test_smooth_surfaces_get_smooth_normals():
    g = mesh("double radius = 2", "Sphere")
    # the normal of a sphere point is its direction from the centre
    n_expected = g.points / np.linalg.norm(g.points, axis=1, keepdims=True)
    assert np.allclose(g.normals, n_expected, atol=1e-5)


@pytest.mark.parametrize(
    ("type_", "body"),
    [
        ("Sphere", "double radius = 0.5"),
        ("Cube", "double size = 2"),
        ("Cylinder", 'double radius = 0.3\ndouble height = 2\nuniform token axis = "X"'),
        ("Cone", 'double radius = 0.4\ndouble height = 1\nuniform token axis = "Y"'),
        ("Capsule", 'double radius = 0.25\ndouble height = 1\nuniform token axis = "Z"'),
    ],
)
def test_implicit_shapes_are_closed_and_face_outwards(type_, body):
    g = mesh(body, type_)
    p3 = g.points[g.indices.astype(int)]
    area = np.linalg.norm(np.cross(p3[:, 1] - p3[:, 0], p3[:, 2] - p3[:, 0]), axis=1)
    ok = area > 1e-10  # poles / apex fans have zero-area triangles
    tn = tri_normals(g)[ok]
    centroid = g.points.mean(axis=0)
    tri_c = p3.mean(axis=1)[ok]
    outward = np.einsum("ij,ij->i", tn, tri_c - centroid)
    assert (outward > -1e-6).mean() > 0.99
    # divergence theorem: a closed, outward surface has a positive volume
    p = g.points[g.indices.astype(int)].astype(np.float64)
    vol = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0
    assert vol > 0


def test_cube_and_sphere_sizes():
    g = mesh("double size = 3", "Cube")
    assert np.allclose(np.abs(g.points).max(axis=0), 1.5)
    g = mesh("double radius = 2", "Sphere")
    assert np.allclose(np.linalg.norm(g.points, axis=1), 2.0, atol=1e-5)


def test_display_color_interpolations():
    g = mesh(QUAD + "\ncolor3f[] primvars:displayColor = [(1, 0, 0)]")
    assert np.allclose(g.display_color, [1, 0, 0]) and g.vertex_colors is None
    g = mesh(
        QUAD
        + "\ncolor3f[] primvars:displayColor = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)] (\n"
        'interpolation = "vertex"\n)'
    )
    assert g.vertex_colors is not None and g.vertex_colors.shape == g.points.shape


def test_inconsistent_topology_is_skipped_with_a_warning():
    g = mesh(
        "int[] faceVertexCounts = [3]\nint[] faceVertexIndices = [0, 1, 9]\n"
        "point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]"
    )
    assert len(g.indices) == 0 and g.warnings
