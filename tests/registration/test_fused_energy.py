"""The registration loop's fused C++ passes equal their torch formulation (value and gradients) within rounding, and
are bit-identical for any number of threads."""

from __future__ import annotations

from typing import Any

import pytest
import torch
import trimesh
from kornia.geometry.conversions import axis_angle_to_rotation_matrix

from tests.reference import fused_unit_vertex_normals
from tests.registration.gt_pairs import torch_threads
from torchmeshmetric import closest_point_on_triangle
from torchmeshmetric.native import try_load
from torchmeshmetric.registration import (
    DeformationGraph,
    data_term,
    embedded_deformation_regularizer,
    interpolated_normals,
    reverse_term,
)
from torchmeshmetric.registration.energies import (
    Correspondences,
    EnergyTerms,
    FusedStep,
    _FusedEnergy,
    deformed_vertices,
    fused_energy,
    registration_ops,
)
from torchmeshmetric.structures import Mesh


def _ops() -> Any:
    assert try_load("bvh") is not None
    ops = registration_ops()
    assert ops is not None
    return ops


def _problem(dtype: torch.dtype = torch.float64, subdivisions: int = 2, spacing: float = 0.3, samples: int = 60):
    """A deformed graph over an icosphere, data points matched to target points, target samples to source points."""
    g = torch.Generator().manual_seed(0)
    src = trimesh.creation.icosphere(subdivisions=subdivisions)
    tgt = trimesh.creation.icosphere(subdivisions=subdivisions + 1)
    sv, sf = torch.tensor(src.vertices, dtype=dtype), torch.tensor(src.faces)
    tv, tf = torch.tensor(tgt.vertices, dtype=dtype) * 1.1, torch.tensor(tgt.faces)
    tf = torch.cat([tf, tf[:1, [0, 0, 1]]])  # a zero-area face: no normal, no point-to-plane part
    graph = DeformationGraph(sv, sf, node_spacing=spacing)
    with torch.no_grad():  # a non-trivial deformation
        graph.rotations.copy_(0.3 * torch.randn(graph.rotations.shape, generator=g, dtype=dtype))
        graph.translations.copy_(0.05 * torch.randn(graph.translations.shape, generator=g, dtype=dtype))
        graph.rotations[0] = 0.0  # the identity and a tiny angle: the series branch of the exponential map's Jacobian
        graph.rotations[1] = torch.tensor([1e-5, -2e-5, 3e-6])
    surf = torch.arange(0, sv.shape[0], 2)
    data_faces = torch.randint(0, tf.shape[0], (surf.numel(),), generator=g)
    data_faces[0] = tf.shape[0] - 1
    # Soft weights: zeros, ones and values between.
    data_w = torch.rand(surf.numel(), generator=g, dtype=dtype).mul(1.25).clamp(max=1.0)
    data_w[torch.rand(surf.numel(), generator=g) < 0.2] = 0.0
    tri = tv[tf[data_faces]]
    closest = closest_point_on_triangle(sv[surf] * 1.05, tri[:, 0], tri[:, 1], tri[:, 2])
    normals = interpolated_normals(Mesh(tv, tf, validate=False).vertex_normals(), tf, data_faces, closest.bary)
    forward = Correspondences(data_faces, data_w, torch.zeros_like(data_w), closest.closest, closest.bary, normals)
    points = tv[torch.randint(0, tv.shape[0], (samples,), generator=g)] * 1.02
    rev_face_idx = torch.randint(0, sf.shape[0], (samples,), generator=g)
    rev_faces = sf[rev_face_idx]
    # Acceptance weights (zeros and ones) times area weights (the registration draws target samples by face index and
    # weights each by its face's area over the mean face area: values above 1 too).
    rev_w = (torch.rand(samples, generator=g, dtype=dtype) > 0.2).to(dtype)
    rev_w = rev_w * torch.rand(samples, generator=g, dtype=dtype).mul(3.0)
    rev_bary = torch.rand(samples, 3, generator=g, dtype=dtype)
    rev_bary = rev_bary / rev_bary.sum(-1, keepdim=True)
    rev_normals = interpolated_normals(Mesh(sv, sf, validate=False).vertex_normals(), sf, rev_face_idx, rev_bary)
    need, inv = torch.cat([surf, rev_faces.reshape(-1)]).unique(return_inverse=True)
    surf_loc, faces_loc = inv[: surf.numel()], inv[surf.numel() :].view(-1, 3)
    reverse = Correspondences(
        torch.arange(samples), rev_w, torch.zeros_like(rev_w), points[:0], rev_bary, rev_normals
    )  # fmt: skip
    terms = EnergyTerms(
        graph.verts[need], graph.vert_nodes[need], graph.vert_weights[need], surf_loc, forward.closest, normals,
        data_w, points, faces_loc, rev_w, rev_bary, rev_normals,
    )  # fmt: skip
    reference = (need, surf_loc, faces_loc, forward, reverse, points)
    return graph, terms, reference


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("plane_weight", [0.0, 1.0])
def test_fused_energy_equals_the_torch_energy(plane_weight: float, threads: int) -> None:
    graph, terms, (need, surf_loc, faces_loc, forward, reverse, samples) = _problem()
    options = {"sigma": 0.05, "plane_weight": plane_weight, "point_weight": 0.1, "reverse_weight": 1.0}

    dsub = graph.deform_vertices(need)
    weights = {"sigma": options["sigma"], "plane_weight": plane_weight, "point_weight": options["point_weight"]}
    expected = data_term(dsub[surf_loc], forward, **weights)
    expected = expected + reverse_term(samples, dsub, faces_loc, reverse, **weights)
    expected = expected * 4.0 + 0.7 * embedded_deformation_regularizer(graph)
    expected.backward()
    grads = [graph.rotations.grad.clone(), graph.translations.grad.clone()]
    graph.zero_grad()

    with torch_threads(threads):
        got = fused_energy(graph, terms, **options, data_scale=4.0, regularization=0.7)
        assert got is not None
        got.backward()
    torch.testing.assert_close(got, expected.detach(), rtol=1e-12, atol=0)
    torch.testing.assert_close(graph.rotations.grad, grads[0], rtol=1e-9, atol=1e-12)
    torch.testing.assert_close(graph.translations.grad, grads[1], rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("threads", [1, 2])
def test_fused_energy_gradient_matches_finite_differences(threads: int) -> None:
    graph, terms, _ = _problem()
    step = FusedStep(graph, terms, _ops())
    scalars = [0.05, 1.0, 0.1, 1.0, 4.0, 0.7]
    rot = graph.rotations.detach().clone().requires_grad_(True)
    tr = graph.translations.detach().clone().requires_grad_(True)
    with torch_threads(threads):
        assert torch.autograd.gradcheck(
            lambda r, t: _FusedEnergy.apply(r, t, step, scalars), (rot, tr), eps=1e-6, atol=1e-6, rtol=1e-5
        )


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_fused_step_is_bit_identical_across_thread_counts(dtype: torch.dtype) -> None:
    # Large enough for many chunks per phase: every sum must keep its order whatever thread runs a chunk.
    graph, terms, _ = _problem(dtype, subdivisions=4, spacing=0.1, samples=3000)
    step = FusedStep(graph, terms, _ops())
    scalars = [0.05, 1.0, 0.1, 1.0, 4.0, 0.7]
    with torch_threads(1):
        one = step(graph.rotations, graph.translations, scalars)
    with torch_threads(2):
        two = step(graph.rotations, graph.translations, scalars)
    for a, b in zip(one, two, strict=True):
        assert torch.equal(a, b)
    grad_max = max(float(one[1].abs().max()), float(one[2].abs().max()))
    assert float(one[3]) == grad_max > 0


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_rotations_are_kornias_bit_for_bit(dtype: torch.dtype, threads: int) -> None:
    g = torch.Generator().manual_seed(1)
    axis = torch.randn(3000, 3, generator=g, dtype=dtype) * torch.logspace(-5, 0.5, 3000, dtype=dtype)[:, None]
    axis[0] = 0.0
    axis[1] = torch.tensor([1e-3, 0.0, 0.0])  # theta^2 = 1e-6: the series branch's edge
    with torch_threads(threads):
        got = _ops().axis_angle_rotations(axis)
    assert (axis * axis).sum(-1).le(1e-6).sum() > 100  # both branches are exercised
    assert torch.equal(got, axis_angle_to_rotation_matrix(axis))


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_deformed_normals_equal_the_mesh_normals(dtype: torch.dtype, threads: int) -> None:
    ops = _ops()
    m = trimesh.creation.icosphere(subdivisions=4)
    verts, faces = torch.tensor(m.vertices, dtype=dtype), torch.tensor(m.faces)
    faces = torch.cat([faces, faces[:2, [0, 0, 1]]])  # zero-area faces
    verts = torch.cat([verts, verts[:1] * 2])  # an unreferenced vertex: no normal
    graph = DeformationGraph(verts, faces, node_spacing=0.2)
    g = torch.Generator().manual_seed(3)
    with torch.no_grad():
        graph.rotations.copy_(0.5 * torch.randn(graph.rotations.shape, generator=g, dtype=dtype))
        graph.translations.copy_(0.1 * torch.randn(graph.translations.shape, generator=g, dtype=dtype))
    at = torch.cat([torch.randperm(verts.shape[0], generator=g)[:1000], torch.tensor([verts.shape[0] - 1])])
    buffers = [t.contiguous() for t in (graph.nodes, graph.verts, graph.vert_nodes, graph.vert_weights)]
    incident = ops.incident_faces(faces, verts.shape[0])
    with torch_threads(threads):
        dv, normals = ops.deform_normals(
            graph.rotations.detach(), graph.translations.detach(), *buffers, faces, *incident, at
        )
    mesh = Mesh(deformed_vertices(graph), faces, validate=False)
    assert torch.equal(dv, mesh.verts)
    # The C++ normals are IEEE 754's operations in a fixed order (std::fma, std::sqrt): the same bits on every CPU.
    exact = fused_unit_vertex_normals(dv.numpy(), faces.numpy())[at.numpy()]
    assert torch.equal(normals, torch.from_numpy(exact))
    assert torch.equal(normals[-1], torch.zeros(3, dtype=dtype))
    # Mesh.vertex_normals (the torch formulation, used on CUDA and without a compiler) equals them bit for bit where
    # torch's cross and norm kernels fuse their multiply-adds (AVX2, AVX-512); its scalar kernels round each product
    # (ATEN_CPU_CAPABILITY=default): there the components differ by at most 1.5 eps (measured 2026-12-06 over six
    # random deformations of this sphere, float32 and float64; 51 % of the rows differ).
    torch_normals = mesh.vertex_normals()[at]
    if torch.backends.cpu.get_cpu_capability() in ("AVX2", "AVX512"):
        assert torch.equal(normals, torch_normals)
    else:
        assert (normals - torch_normals).abs().max() <= 2 * torch.finfo(dtype).eps


def test_deformed_vertices_equal_the_graph() -> None:
    m = trimesh.creation.icosphere(subdivisions=3)
    graph = DeformationGraph(torch.tensor(m.vertices), torch.tensor(m.faces), node_spacing=0.2)
    with torch.no_grad():
        graph.rotations.copy_(0.5 * torch.randn(graph.rotations.shape, dtype=torch.float64))
        graph.translations.copy_(torch.randn(graph.translations.shape, dtype=torch.float64))
    torch.testing.assert_close(deformed_vertices(graph), graph().detach(), rtol=0, atol=1e-14)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_farthest_point_nodes_in_cpp_equal_the_torch_loop(monkeypatch: pytest.MonkeyPatch, dtype: torch.dtype) -> None:
    from torchmeshmetric import native
    from torchmeshmetric.registration import farthest_point_nodes

    g = torch.Generator().manual_seed(2)
    points = torch.rand(3000, 3, generator=g, dtype=dtype).mul(4).round()  # a lattice: many equal distances
    points = torch.cat([points, torch.rand(2000, 3, generator=g, dtype=dtype)])
    fast = farthest_point_nodes(points, 0.3)
    monkeypatch.setattr(native, "try_load", lambda name: None)  # the torch loop
    assert torch.equal(fast, farthest_point_nodes(points, 0.3))


def test_energy_terms_equal_the_torch_layout() -> None:
    """The C++ layout of one refresh's terms: the rows unique(return_inverse=True) and plain gathers give."""
    ops = _ops()
    g = torch.Generator().manual_seed(4)
    src = trimesh.creation.icosphere(subdivisions=3)
    sv, sf = torch.tensor(src.vertices), torch.tensor(src.faces)
    graph = DeformationGraph(sv, sf, node_spacing=0.3)
    surf = torch.randperm(sv.shape[0], generator=g)[:200]
    rev_idx = torch.randint(0, sf.shape[0], (150,), generator=g)
    data_w, rev_w = torch.rand(200, generator=g, dtype=torch.float64), torch.rand(150, generator=g, dtype=torch.float64)
    skin = [t.contiguous() for t in (graph.verts, graph.vert_nodes, graph.vert_weights)]
    out = ops.energy_terms(surf, rev_idx, sf, *skin, data_w, rev_w, graph.nodes, graph.edges)
    need, inv = torch.cat([surf, sf[rev_idx].reshape(-1)]).unique(return_inverse=True)
    expected = [
        need, graph.verts[need], graph.vert_nodes[need], graph.vert_weights[need], inv[:200], inv[200:].view(-1, 3)
    ]  # fmt: skip
    expected += ops.energy_layout(expected[4], data_w, expected[5], rev_w, expected[2], graph.nodes, graph.edges)
    assert len(out) == len(expected) == 13
    for got, want in zip(out, expected, strict=True):
        assert torch.equal(got, want)
    with pytest.raises(RuntimeError, match="face index out of range"):
        ops.energy_terms(surf, rev_idx + sf.shape[0], sf, *skin, data_w, rev_w, graph.nodes, graph.edges)
    with pytest.raises(RuntimeError, match="data index out of range"):
        ops.energy_terms(surf + sv.shape[0], rev_idx, sf, *skin, data_w, rev_w, graph.nodes, graph.edges)
