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


def test_mesh_k_and_the_options_are_checked_as_in_the_other_simplifiers(spheres):
    # A Mesh built with validate=False skips the constructor's checks. NaN vertices came back in the output without a
    # word (no anchors, or weight 0) or were refused under the nearest-anchor query's own name "ref_points"; integer
    # vertices ended in "ref_points: reference set 0 is empty"; candidate_fraction="0.5" and min_normal_cos="0.2" gave
    # Python's "'<' not supported between instances of 'float' and 'str'" (found by review G).
    from torchmeshmetric import DTypeError
    from torchmeshmetric.simplification import simplify_qem

    uv, previous = spheres
    verts = uv.verts.clone()
    verts[3] = float("nan")
    nan_mesh = Mesh(verts, uv.faces, validate=False)
    for anchors, weight in ((previous.verts[:0], 0.1), (previous.verts, 0.0), (previous.verts, 0.1)):
        with pytest.raises(NonFiniteError, match=r"^mesh_k\.verts: expected finite values, found 3 NaN/Inf"):
            simplify_anchored_qem(nan_mesh, anchors, 400, weight=weight)
    with pytest.raises(
        DTypeError, match=r"^mesh_k\.verts: expected a floating-point tensor .* found dtype torch.int64"
    ):
        simplify_anchored_qem(Mesh(uv.verts.long(), uv.faces, validate=False), previous.verts, 400)
    half = Mesh(uv.verts.half(), uv.faces, validate=False)  # refused everywhere else, accepted by the simplifiers
    for simplify, name in (
        (lambda m: simplify_anchored_qem(m, previous.verts, 400), "mesh_k"),
        (lambda m: simplify_registered_qem(m, None, 400), "mesh_k"),
        (lambda m: simplify_registered_qem(uv, m, 400), "registered_mesh_k_minus_1"),
        (lambda m: simplify_qem(m, 400), "mesh"),
    ):
        with pytest.raises(
            DTypeError, match=rf"^{name}\.verts: expected float32 or float64, found dtype torch.float16"
        ):
            simplify(half)
    for option, value in (("candidate_fraction", "0.5"), ("min_normal_cos", "0.2"), ("candidate_fraction", True)):
        message = rf"^{option}: expected a float, found (str|bool) {value!r}"
        with pytest.raises(TypeError, match=message):
            simplify_anchored_qem(uv, previous.verts, 400, **{option: value})
        with pytest.raises(TypeError, match=message):
            simplify_registered_qem(uv, None, 400, **{option: value})
