"""Anchored QEM: the survivors follow the anchors (the previous frame's vertices), plain QEM at weight 0."""

import pytest
import torch
import trimesh

from torchmeshmetric import EmptyInputError, Mesh, as_mesh, nearest_vertex_distance, point_mesh_distance
from torchmeshmetric._checks import NonFiniteError, ShapeError
from torchmeshmetric.simplification import simplify_anchored_qem, simplify_registered_qem


@pytest.fixture(scope="module")
def spheres():
    """Two unrelated tessellations of the unit sphere, and a 400-face simplification of the first (the anchors)."""
    ico = as_mesh(trimesh.creation.icosphere(subdivisions=4)).to(dtype=torch.float64)
    uv = as_mesh(trimesh.creation.uv_sphere(count=[48, 48])).to(dtype=torch.float64)
    previous = simplify_anchored_qem(ico, ico.verts[:0], 400)
    return uv, previous


def _mean_edge(mesh: Mesh) -> float:
    return float((mesh.verts[mesh.faces[:, 0]] - mesh.verts[mesh.faces[:, 1]]).norm(dim=1).mean())


def _flicker(a: Mesh, b: Mesh) -> float:
    return float((point_mesh_distance(a.verts, b).dists.mean() + point_mesh_distance(b.verts, a).dists.mean()) / 2)


def test_weight_zero_is_the_plain_queue(spheres):
    uv, previous = spheres
    a = simplify_anchored_qem(uv, previous.verts, 400, weight=0.0)
    b = simplify_registered_qem(uv, None, 400)
    assert torch.equal(a.verts, b.verts) and torch.equal(a.faces, b.faces)


def test_survivors_follow_the_anchors_on_another_tessellation(spheres):
    # Measured on this pair: the mean distance of a vertex to its nearest anchor is 0.366 edge lengths at weight 0,
    # 0.053 at 0.3 and 0.019 at 10; the two-sided mean surface distance to the anchors' mesh 1.03e-2, 3.3e-3, 1.4e-3.
    uv, previous = spheres
    h = _mean_edge(previous)
    out = {w: simplify_anchored_qem(uv, previous.verts, 400, weight=w) for w in (0.0, 0.3, 10.0)}
    near = {w: float(nearest_vertex_distance(m.verts, previous.verts).dists.mean()) / h for w, m in out.items()}
    assert near[0.0] > 0.3 and near[0.3] < 0.07 and near[10.0] < near[0.3]
    assert _flicker(out[0.3], previous) < 0.4 * _flicker(out[0.0], previous)
    assert all(m.num_faces in (400, 401) for m in out.values())
    tm = out[0.3].to_trimesh()
    assert tm.is_watertight and tm.is_winding_consistent and tm.euler_number == 2


def test_per_anchor_weights_equal_to_a_float_give_the_same_mesh(spheres):
    uv, previous = spheres
    per_anchor = torch.full((previous.num_verts,), 0.3, dtype=torch.float64)
    a = simplify_anchored_qem(uv, previous.verts, 400, weight=per_anchor)
    b = simplify_anchored_qem(uv, previous.verts, 400, weight=0.3)
    assert torch.equal(a.verts, b.verts) and torch.equal(a.faces, b.faces)


def test_bad_input_is_named(spheres):
    uv, previous = spheres
    with pytest.raises(ShapeError, match="anchors"):
        simplify_anchored_qem(uv, previous.verts[:, :2], 400)
    with pytest.raises(NonFiniteError, match="anchors"):
        simplify_anchored_qem(uv, previous.verts * float("nan"), 400)
    with pytest.raises(ValueError, match="weight"):
        simplify_anchored_qem(uv, previous.verts, 400, weight=-1.0)
    with pytest.raises(ShapeError, match="weight"):
        simplify_anchored_qem(uv, previous.verts, 400, weight=torch.ones(3, dtype=torch.float64))
    with pytest.raises(TypeError, match="weight"):
        simplify_anchored_qem(uv, previous.verts, 400, weight="1")  # type: ignore[arg-type]
    with pytest.raises(EmptyInputError, match="mesh_k"):
        simplify_anchored_qem(Mesh(uv.verts, uv.faces[:0]), previous.verts, 1)
