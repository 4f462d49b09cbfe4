"""Numbers at the edges: meshes of extreme magnitude (exact power-of-two scaling), half precision (typed error on
every entry point and backend), losses on empty point sets."""

from __future__ import annotations

import pytest
import torch
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

import torchmeshmetric as tmm
from torchmeshmetric import DTypeError, EmptyInputError, NonFiniteError
from torchmeshmetric.native import try_load

SPHERE = trimesh.creation.icosphere(subdivisions=1)
FACE_BACKENDS = ["bruteforce", "bvh", "pruned", "auto"]
NEAREST_BACKENDS = ["bruteforce", "bvh", "pruned", "auto"]
# Query points: outside, inside (face region), on the sphere's vertices, near an edge.
POINTS = torch.tensor([[0.0, 0.0, 3.0], [0.3, 0.2, 0.1], [2.0, 1.0, 0.0], [0.1, -0.05, 0.02]], dtype=torch.float64)


@pytest.fixture(scope="module", autouse=True)
def _compiled() -> None:
    assert try_load("bvh") is not None


def _scaled(scale: float, dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    verts = (torch.tensor(SPHERE.vertices) * scale).to(dtype)
    points = (torch.cat([POINTS, torch.tensor(SPHERE.vertices[:3])]) * scale).to(dtype)
    return points, verts, torch.tensor(SPHERE.faces)


def _reference(points: torch.Tensor, verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """float64 distances of the same (rounded) inputs, computed at unit magnitude (exact power-of-two scaling)."""
    s = 2.0 ** -int(torch.frexp(verts.abs().amax().double()).exponent)
    return tmm.point_mesh_distance(points.double() * s, verts.double() * s, faces, backend="bruteforce").dists / s


@settings(max_examples=12, deadline=None)
@given(exponent=st.integers(-120, 120), mantissa=st.floats(1.0, 1.9))
@pytest.mark.parametrize("backend", FACE_BACKENDS)
def test_float32_point_mesh_distance_is_exact_at_any_magnitude(backend, exponent, mantissa):
    scale = mantissa * 2.0**exponent
    points, verts, faces = _scaled(scale, torch.float32)
    got = tmm.point_mesh_distance(points, verts, faces, backend=backend)
    ref = _reference(points, verts, faces)
    diag = float((verts.double().amax(0) - verts.double().amin(0)).norm())
    assert torch.isfinite(got.dists).all()
    torch.testing.assert_close(got.dists.double(), ref, rtol=0, atol=2e-6 * diag)
    assert (got.closest.double() - verts.double().mean(0)).abs().max() <= 4 * diag


@settings(max_examples=8, deadline=None)
@given(exponent=st.integers(-900, 900))
def test_float64_point_mesh_distance_is_exact_at_any_magnitude(exponent):
    points, verts, faces = _scaled(1.37 * 2.0**exponent, torch.float64)
    got = tmm.point_mesh_distance(points, verts, faces)
    ref = _reference(points, verts, faces)
    diag = float((verts.amax(0) - verts.amin(0)).norm())
    torch.testing.assert_close(got.dists, ref, rtol=0, atol=1e-13 * diag)


@settings(max_examples=12, deadline=None)
@given(exponent=st.integers(-120, 120))
@pytest.mark.parametrize("backend", NEAREST_BACKENDS)
@pytest.mark.parametrize("grad", [False, True])
def test_float32_nearest_vertex_distance_is_exact_at_any_magnitude(backend, grad, exponent):
    points, verts, _ = _scaled(1.23 * 2.0**exponent, torch.float32)
    points.requires_grad_(grad)
    got = tmm.nearest_vertex_distance(points, verts, backend=backend)
    s = 2.0 ** -int(torch.frexp(verts.abs().amax().double()).exponent)
    ref = tmm.nearest_vertex_distance(points.detach().double() * s, verts.double() * s).dists / s
    diag = float((verts.double().amax(0) - verts.double().amin(0)).norm())
    torch.testing.assert_close(got.dists.detach().double(), ref, rtol=0, atol=2e-6 * diag)
    packed = tmm.nearest_vertex_distance([points.detach()], [verts], backend=backend)
    torch.testing.assert_close(packed.dists.double(), ref, rtol=0, atol=2e-6 * diag)


@pytest.mark.parametrize("backend", FACE_BACKENDS)
@pytest.mark.parametrize(("dtype", "exponent"), [(torch.float32, -133), (torch.float32, -140), (torch.float64, -1030)])
def test_subnormal_extents_are_measured_on_every_backend(backend, dtype, exponent):
    # Review V, F2: the range scale for an extent below the smallest normal was not representable (float32 1e-40:
    # 2**132 = inf; float64 1e-310: OverflowError from math.ldexp); each backend then failed its own way ("distances
    # overflow ... too large", IndexError, torch.cat of an empty list). The scale is now capped at the largest finite
    # power of two. The reference: the same (rounded) inputs scaled exactly into float64's normal range.
    points, verts, faces = _scaled(1.3 * 2.0**exponent, dtype)
    assert 0 < float(verts.abs().amax()) < torch.finfo(dtype).tiny
    up = 2.0**600
    ref_face = tmm.point_mesh_distance(points.double() * up, verts.double() * up, faces, backend="bruteforce").dists
    ref_vert = tmm.nearest_vertex_distance(points.double() * up, verts.double() * up, backend="bruteforce").dists
    # Subnormal inputs carry few bits, but are exact; the distances are computed at unit magnitude (float32 rel.
    # 2e-6 of the diagonal, as at any magnitude above) and rounded once to the subnormal grid (half its spacing).
    diag = float((verts.double().amax(0) - verts.double().amin(0)).norm())
    spacing = torch.finfo(dtype).tiny * torch.finfo(dtype).eps  # the subnormals' spacing
    atol = (2e-6 if dtype == torch.float32 else 1e-13) * diag + spacing
    for got, ref in (
        (tmm.point_mesh_distance(points, verts, faces, backend=backend).dists, ref_face),
        (tmm.MeshIndex(verts, faces, backend=backend).point_mesh_distance(points).dists, ref_face),
        (tmm.nearest_vertex_distance(points, verts, backend=backend).dists, ref_vert),
    ):
        torch.testing.assert_close(got.double(), ref / up, rtol=0, atol=atol)


@pytest.mark.parametrize("scale", [1e12, 1e20, 1e30, 1e-12, 1e-20])
def test_statistics_and_psnr_at_extreme_magnitudes(scale):
    ref = tmm.Mesh((torch.tensor(SPHERE.vertices) * scale).float(), torch.tensor(SPHERE.faces))
    coarse = trimesh.creation.icosphere(subdivisions=0)
    simp = tmm.Mesh((torch.tensor(coarse.vertices) * 1.01 * scale).float(), torch.tensor(coarse.faces))
    unit = tmm.evaluate_pair(
        tmm.Mesh(simp.verts.double() / scale, simp.faces),
        tmm.Mesh(ref.verts.double() / scale, ref.faces),
        tmm.Mesh(ref.verts.double() / scale, ref.faces),
        precomputed_registration=tmm.Mesh(ref.verts.double() / scale, ref.faces),
    ).statistics["surface_k"]
    got = tmm.evaluate_pair(simp, ref, ref, precomputed_registration=ref).statistics["surface_k"]
    assert float(got.ave) / scale == pytest.approx(float(unit.ave), rel=1e-5)
    assert float(got.max) / scale == pytest.approx(float(unit.max), rel=1e-5)
    assert float(got.psnr) == pytest.approx(float(unit.psnr), abs=1e-3)


def test_distances_beyond_the_dtype_range_are_an_error_not_inf():
    verts = torch.tensor(SPHERE.vertices, dtype=torch.float32)
    far = torch.tensor([[0.0, 0.0, 3e30]])
    # Review D, finding 4: this test pinned the refusal of 3e30 by point_mesh_distance, whose scale came from the
    # mesh alone; 3e30 is representable, and the function now scales for its points too, as nearest_vertex_distance
    # does. An index's scale is fixed by its mesh: its query's square overflows, and it refuses.
    got32 = tmm.point_mesh_distance(far, verts, torch.tensor(SPHERE.faces), backend="bruteforce").dists.item()
    assert got32 == pytest.approx(3e30 - 1, rel=1e-6)
    with pytest.raises(NonFiniteError, match=r"overflow torch.float32 .* compute in float64"):
        tmm.MeshIndex(verts, torch.tensor(SPHERE.faces), backend="bruteforce").point_mesh_distance(far)
    # A distance float32 cannot hold (6e38 > 3.4e38) is refused by the function too.
    with pytest.raises(NonFiniteError, match=r"overflow torch.float32 .* compute in float64"):
        tmm.point_mesh_distance(
            torch.tensor([[0.0, 0.0, 3e38]]), verts - 3e38, torch.tensor(SPHERE.faces), backend="bruteforce"
        )
    # nearest-vertex distances scale with the points too: 3e30 is representable, so it is the answer
    assert tmm.nearest_vertex_distance(far, verts).dists.item() == pytest.approx(3e30 - 1, rel=1e-6)
    far64 = torch.tensor([[0.0, 0.0, 3e30]], dtype=torch.float64)
    got = tmm.point_mesh_distance(far64, verts.double(), torch.tensor(SPHERE.faces)).dists.item()
    assert got == pytest.approx(3e30 - 1, rel=1e-12)


@pytest.mark.parametrize("backend", NEAREST_BACKENDS)
def test_nearest_vertex_distance_to_a_tiny_reference_set_is_scaled_for_the_points_too(backend):
    # The squares of the points' distances fit float32; scaling by the 1e-20 reference extent alone would not.
    ref = torch.tensor([[0.0, 0, 0], [1e-20, 0, 0], [0, 1e-20, 0]])
    points = torch.tensor([[1.0, 0, 0], [0, 0, 2.0]])
    for got in (
        tmm.nearest_vertex_distance(points, ref, backend=backend),
        tmm.nearest_vertex_distance([points], [ref], backend=backend),
    ):
        assert got.dists.tolist() == [1.0, 2.0]
        assert got.idx.tolist() == [0, 0]  # equal computed squares: the lowest index


def test_index_nearest_distances_beyond_the_dtype_range_are_an_error_not_inf():
    index = tmm.MeshIndex(torch.tensor(SPHERE.vertices, dtype=torch.float32), torch.tensor(SPHERE.faces))
    with pytest.raises(NonFiniteError, match=r"overflow torch.float32 .* compute in float64"):
        index.nearest_vertex_distance(torch.tensor([[0.0, 0.0, 3e30]]))


# ------------------------------------------------------------------------------------------------ half precision
def _half_calls(dtype):
    v = torch.tensor(SPHERE.vertices).to(dtype)
    f = torch.tensor(SPHERE.faces)
    p = POINTS.to(dtype)
    v32 = v.float()
    calls = {
        f"point_mesh_distance[{b}]": (lambda b=b: tmm.point_mesh_distance(p, v, f, backend=b)) for b in FACE_BACKENDS
    }
    calls |= {
        f"point_mesh_distance[{b}, half points only]": (lambda b=b: tmm.point_mesh_distance(p, v32, f, backend=b))
        for b in FACE_BACKENDS
    }
    calls |= {f"nearest[{b}]": (lambda b=b: tmm.nearest_vertex_distance(p, v, backend=b)) for b in NEAREST_BACKENDS}
    calls |= {
        "nearest[list]": lambda: tmm.nearest_vertex_distance([p], [v32]),
        "closest_point_on_triangle": lambda: tmm.closest_point_on_triangle(p, v[:4], v[1:5], v[2:6]),
        "Mesh": lambda: tmm.Mesh(v, f),
        "sample_surface": lambda: tmm.sample_surface(v, f, 10),
        "MeshSurfaceDistance": lambda: tmm.MeshSurfaceDistance()(p, (v32, f)),
        "NearestVertexDistance": lambda: tmm.NearestVertexDistance()(p, v32),
        "mesh_surface_distance_loss": lambda: tmm.mesh_surface_distance_loss(p, (v32, f)),
        "nearest_vertex_distance_loss": lambda: tmm.nearest_vertex_distance_loss(p, v32),
        "register_rigid": lambda: tmm.register_rigid((v, f), (v32, f)),
        "register_nonrigid": lambda: tmm.register_nonrigid((v32, f), (v, f)),
        "evaluate_pair": lambda: tmm.evaluate_pair((v, f), (v32, f), (v32, f)),
        "simplify_qem": lambda: tmm.simplify_qem((v, f), 0.5),
    }
    return calls


@pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16])
@pytest.mark.parametrize("entry", sorted(_half_calls(torch.float16)))
def test_half_precision_is_a_typed_error_on_every_entry_point(dtype, entry):
    with pytest.raises(DTypeError, match=rf"expected float32 or float64, found dtype {dtype}; half precision"):
        _half_calls(dtype)[entry]()


# ------------------------------------------------------------------------------------------------ empty losses
LOSSES = [tmm.mesh_surface_distance_loss, tmm.nearest_vertex_distance_loss]


@pytest.mark.parametrize("loss", LOSSES)
@pytest.mark.parametrize("simplified", [torch.zeros(0, 3), [torch.zeros(0, 3)], [torch.zeros(0, 3)] * 3])
def test_loss_mean_over_an_empty_point_set_raises_like_the_metrics(loss, simplified):
    refs = (torch.tensor(SPHERE.vertices).float(), torch.tensor(SPHERE.faces))
    reference = [refs] * len(simplified) if isinstance(simplified, list) else refs
    with pytest.raises(EmptyInputError, match="simplified: the batch holds no point"):
        loss(simplified, reference)
    assert loss(simplified, reference, reduction="sum").item() == 0.0
    assert loss(simplified, reference, reduction="none").shape == (0,)


@pytest.mark.parametrize("loss_cls", [tmm.MeshSurfaceDistanceLoss, tmm.NearestVertexDistanceLoss])
def test_loss_module_on_an_empty_point_set_raises(loss_cls):
    refs = (torch.tensor(SPHERE.vertices).float(), torch.tensor(SPHERE.faces))
    with pytest.raises(EmptyInputError):
        loss_cls()(torch.zeros(0, 3), refs)


def test_loss_mean_with_some_empty_items_pools_the_others():
    refs = (torch.tensor(SPHERE.vertices).float(), torch.tensor(SPHERE.faces))
    x = torch.tensor([[0.0, 0.0, 3.0]])
    got = tmm.mesh_surface_distance_loss([torch.zeros(0, 3), x], [refs, refs])
    assert got.item() == pytest.approx(tmm.mesh_surface_distance_loss(x, refs).item())


# One far query point among near ones: float32 and float64, beyond the range the mesh's own frame keeps.
FAR_POINTS = [(torch.float32, 1e10), (torch.float32, 1e18), (torch.float32, 1e30), (torch.float64, 1e150)]


def _near_points(dtype: torch.dtype) -> torch.Tensor:
    g = torch.Generator().manual_seed(0)
    return torch.cat([POINTS, 1.5 * (2 * torch.rand(200, 3, generator=g, dtype=torch.float64) - 1)]).to(dtype)


@pytest.mark.parametrize("backend", FACE_BACKENDS)
@pytest.mark.parametrize(("dtype", "far"), FAR_POINTS)
def test_one_far_query_point_leaves_the_others_in_the_meshs_frame(backend, dtype, far):
    # Found while fixing review I #1: the function scaled every point for its farthest one, so one float32 point at
    # 1e10 moved the other distances to a unit sphere by 0.031 (their faces' squared areas fell into subnormals), one
    # at 1e30 made them all 0. The near points are now measured in the mesh's own frame (as a MeshIndex measures
    # them, bit for bit), the far one in a frame scaled for it too.
    verts, faces = torch.tensor(SPHERE.vertices, dtype=dtype), torch.tensor(SPHERE.faces)
    near = _near_points(dtype).requires_grad_()
    far_point = torch.tensor([[0.0, far, 0.0]], dtype=dtype, requires_grad=True)
    got = tmm.point_mesh_distance(torch.cat([near[:100], far_point, near[100:]]), verts, faces, backend=backend)
    alone = tmm.point_mesh_distance(near, verts, faces, backend=backend)
    kept = tmm.MeshIndex(verts, faces, backend=backend).point_mesh_distance(near.detach())
    rows = torch.cat([torch.arange(100), torch.arange(101, near.shape[0] + 1)])
    for name, a, b, c in zip(got._fields, got, alone, kept, strict=True):
        assert torch.equal(a[rows], b) and torch.equal(b, c), name
    truth = tmm.point_mesh_distance(near.detach().double(), verts.double(), faces, backend="bruteforce").dists
    torch.testing.assert_close(got.dists[rows].double(), truth, rtol=0, atol=8 * torch.finfo(dtype).eps)
    assert float(got.dists[100].detach()) == pytest.approx(far - 1, rel=8 * torch.finfo(dtype).eps)
    # Gradients of the near points are those of the call without the far point; the far point's is its direction.
    (g_near, g_far) = torch.autograd.grad(got.dists.sum(), (near, far_point))
    (g_alone,) = torch.autograd.grad(alone.dists.sum(), (near,))
    assert torch.equal(g_near, g_alone)
    torch.testing.assert_close(g_far, torch.tensor([[0.0, 1.0, 0.0]], dtype=dtype))


@pytest.mark.parametrize("backend", NEAREST_BACKENDS)
@pytest.mark.parametrize(("dtype", "far"), [(torch.float32, 1e30), (torch.float64, 1e300)])
def test_one_far_query_point_leaves_the_others_in_the_reference_sets_frame(backend, dtype, far):
    # float32, unit reference set, a point at 1e30: the other points' nearest distances came out 0.
    ref = torch.tensor(SPHERE.vertices, dtype=dtype)
    near = _near_points(dtype)
    pts = torch.cat([near, torch.tensor([[far, 0.0, 0.0]], dtype=dtype)])
    alone = tmm.nearest_vertex_distance(near, ref, backend=backend)
    for got in (
        tmm.nearest_vertex_distance(pts, ref, backend=backend),
        tmm.nearest_vertex_distance([pts], [ref], backend=backend),
    ):
        assert torch.equal(got.dists[:-1], alone.dists) and torch.equal(got.idx[:-1], alone.idx)
        assert float(got.dists[-1]) == pytest.approx(far - 1, rel=8 * torch.finfo(dtype).eps)


def test_tiny_meshes_measure_near_points_in_their_own_frame_and_far_ones_too():
    # A float32 triangle of size 1e-20: a point at distance 1 is measured (a frame scaled for it), and no longer
    # takes the point 2e-20 above the triangle with it (that frame's squared areas underflowed: 2.00998e-20).
    tri, face = torch.tensor([[0.0, 0, 0], [1e-20, 0, 0], [0, 1e-20, 0]]), torch.tensor([[0, 1, 2]])
    pts = torch.tensor([[3e-21, 2e-21, 2e-20], [0.0, 0.0, 1.0]])
    got = tmm.point_mesh_distance(pts, tri, face).dists
    assert got.tolist() == [tmm.point_mesh_distance(pts[:1], tri, face).dists.item(), 1.0]
    assert got[0].item() == pytest.approx(2e-20, rel=1e-6)
    # Nearest vertex: the fused unscaled path overflows on the far point; the near one was 0, it is 5e-21.
    near = tmm.nearest_vertex_distance(torch.tensor([[1.3e-20, 0.4e-20, 0.0], [0.0, 0.0, 1e30]]), tri).dists
    assert near[0].item() == pytest.approx(5e-21, rel=1e-6) and near[1].item() == pytest.approx(1e30, rel=1e-6)


def test_a_packed_batch_splits_its_points_by_frame_per_item():
    verts, faces = torch.tensor(SPHERE.vertices, dtype=torch.float32), torch.tensor(SPHERE.faces)
    near = _near_points(torch.float32)
    first = torch.cat([near[:50], torch.tensor([[1e30, 0.0, 0.0]])])
    meshes = [(verts, faces), (verts * 0.5 + 2.0, faces)]
    got = tmm.point_mesh_distance([first, near + 2.0], meshes)
    kept = tmm.MeshIndex(meshes).point_mesh_distance([near[:50], near + 2.0])
    rows = torch.cat([torch.arange(50), torch.arange(51, 51 + near.shape[0])])
    for name, a, b in zip(got._fields, got, kept, strict=True):
        assert torch.equal(a[rows], b), name
    assert float(got.dists[50]) == pytest.approx(1e30, rel=1e-6)
