"""Geometry builders: icospheres (section 5.2) and straight rods (section 5.1)."""

import numpy as np
import pytest

from parastokes.bodies import geometry


@pytest.mark.parametrize("level", [0, 1, 2, 3])
def test_icosphere_counts_and_topology(level):
    verts, tris = geometry.icosphere(level)
    edges = geometry.mesh_edges(tris)
    assert verts.shape == (10 * 4**level + 2, 3)
    assert tris.shape == (20 * 4**level, 3)
    assert edges.shape == (30 * 4**level, 2)
    assert len(verts) - len(edges) + len(tris) == 2  # Euler characteristic of the sphere
    np.testing.assert_allclose(np.linalg.norm(verts, axis=1), 1.0, rtol=0, atol=1e-15)
    # every edge is shared by exactly two triangles, with opposite orientations (closed, oriented)
    directed = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    assert len({tuple(e) for e in directed}) == len(directed)
    assert {tuple(e) for e in directed} == {tuple(e[::-1]) for e in directed}


def test_icosphere_level3_matches_paper():
    verts, tris = geometry.icosphere(3)
    edges = geometry.mesh_edges(tris)
    assert (len(verts), len(tris), len(edges)) == (642, 1280, 1920)
    assert geometry.edge_lengths(verts, edges).max() == pytest.approx(0.165, abs=5e-4)


def test_icosphere_outward_and_area_converges():
    areas = []
    for level in range(5):
        verts, tris = geometry.icosphere(level)
        a, b, c = (verts[tris[:, i]] for i in range(3))
        volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
        assert volume > 0  # outward normals give a positive signed volume
        areas.append(geometry.surface_area(verts, tris))
    assert np.all(np.diff(areas) > 0)  # inscribed polyhedra grow toward the sphere
    errors = 4 * np.pi - np.array(areas)
    # refinement halves the edge length: the area error falls about fourfold
    np.testing.assert_allclose(errors[3:] / errors[2:-1], 0.25, rtol=0.02)


def test_icosphere_is_cached_and_read_only():
    verts, _ = geometry.icosphere(2)
    assert geometry.icosphere(2)[0] is verts
    with pytest.raises(ValueError):
        verts[0, 0] = 2.0


def test_icosphere_rejects_negative_level():
    with pytest.raises(ValueError, match="subdivisions"):
        geometry.icosphere(-1)


def test_straight_rods_layout():
    x = geometry.straight_rods(3, 301, 60.0, 10.0, 5.0)
    assert x.shape == (903, 12)
    rods = x.reshape(3, 301, 12)
    np.testing.assert_allclose(np.diff(rods[:, :, 0], axis=1), 0.2, rtol=1e-12)
    np.testing.assert_array_equal(rods[:, 0, 1], [-5.0, 0.0, 5.0])
    np.testing.assert_array_equal(rods[:, :, 2], 10.0)
    # D1 = e_y, D2 = e_z, D3 = e_x
    np.testing.assert_array_equal(rods[0, 0, 3:], [0, 1, 0, 0, 0, 1, 1, 0, 0])
    d1, d2, d3 = rods[0, 0, 3:6], rods[0, 0, 6:9], rods[0, 0, 9:12]
    np.testing.assert_array_equal(np.cross(d1, d2), d3)  # right-handed


@pytest.mark.parametrize(("n_rods", "n_points"), [(0, 10), (1, 1), (1, -5)])
def test_straight_rods_rejects_bad_sizes(n_rods, n_points):
    with pytest.raises(ValueError, match="n_rods" if n_rods < 1 else "n_points"):
        geometry.straight_rods(n_rods, n_points, 1.0, 1.0, 1.0)
