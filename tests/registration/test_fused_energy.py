"""The registration loop's fused C++ energy equals its torch formulation (value and gradients) within rounding."""

from __future__ import annotations

import pytest
import torch
import trimesh

from torchmeshmetric.kernels.accel._extension import load_bvh
from torchmeshmetric.registration import DeformationGraph, embedded_deformation_regularizer, surface_term
from torchmeshmetric.registration.energies import Correspondences, EnergyTerms, deformed_vertices, fused_energy
from torchmeshmetric.structures import Mesh


@pytest.mark.parametrize("plane_weight", [0.0, 1.0])
def test_fused_energy_equals_the_torch_energy(plane_weight: float) -> None:
    assert load_bvh() is not None
    g = torch.Generator().manual_seed(0)
    src = trimesh.creation.icosphere(subdivisions=2)
    tgt = trimesh.creation.icosphere(subdivisions=3)
    sv, sf = torch.tensor(src.vertices), torch.tensor(src.faces)
    tv, tf = torch.tensor(tgt.vertices) * 1.1, torch.tensor(tgt.faces)
    tf = torch.cat([tf, tf[:1, [0, 0, 1]]])  # a zero-area face: no normal, no point-to-plane part
    graph = DeformationGraph(sv, sf, node_spacing=0.3)
    with torch.no_grad():  # a non-trivial deformation
        graph.rotations.copy_(0.3 * torch.randn(graph.rotations.shape, generator=g, dtype=torch.float64))
        graph.translations.copy_(0.05 * torch.randn(graph.translations.shape, generator=g, dtype=torch.float64))
        graph.rotations[0] = 0.0  # the identity and a tiny angle: the series branch of the exponential map's Jacobian
        graph.rotations[1] = torch.tensor([1e-5, -2e-5, 3e-6])
    surf = torch.arange(0, sv.shape[0], 2)
    data_faces = torch.randint(0, tf.shape[0], (surf.numel(),), generator=g)
    data_faces[0] = tf.shape[0] - 1
    data_w = (torch.rand(surf.numel(), generator=g, dtype=torch.float64) > 0.2).double()
    samples = tv[torch.randint(0, tv.shape[0], (60,), generator=g)] * 1.02
    rev_faces = sf[torch.randint(0, sf.shape[0], (60,), generator=g)]
    rev_w = (torch.rand(60, generator=g, dtype=torch.float64) > 0.2).double()
    need, inv = torch.cat([surf, rev_faces.reshape(-1)]).unique(return_inverse=True)
    surf_loc, faces_loc = inv[: surf.numel()], inv[surf.numel() :].view(-1, 3)
    options = {"sigma": 0.05, "plane_weight": plane_weight, "point_weight": 0.1, "reverse_weight": 1.0}

    dsub = graph.deform_vertices(need)
    corr_f = Correspondences(data_faces, data_w, torch.zeros_like(data_w))
    corr_r = Correspondences(torch.arange(60), rev_w, torch.zeros_like(rev_w))
    sigma, pw, qw = options["sigma"], options["plane_weight"], options["point_weight"]
    expected = surface_term(dsub[surf_loc], tv, tf, corr_f, sigma=sigma, plane_weight=pw, point_weight=qw)
    expected = expected + surface_term(samples, dsub, faces_loc, corr_r, sigma=sigma, plane_weight=0, point_weight=1)
    expected = expected * 4.0 + 0.7 * embedded_deformation_regularizer(graph)
    expected.backward()
    grads = [graph.rotations.grad.clone(), graph.translations.grad.clone()]
    graph.zero_grad()

    terms = EnergyTerms(
        graph.verts[need], graph.vert_nodes[need], graph.vert_weights[need], surf_loc, tv[tf[data_faces]],
        Mesh(tv, tf, validate=False).face_normals()[data_faces], data_w, samples, faces_loc, rev_w,
    )  # fmt: skip
    got = fused_energy(graph, terms, **options, data_scale=4.0, regularization=0.7)
    assert got is not None
    got.backward()
    torch.testing.assert_close(got, expected.detach(), rtol=1e-12, atol=0)
    torch.testing.assert_close(graph.rotations.grad, grads[0], rtol=1e-9, atol=1e-12)
    torch.testing.assert_close(graph.translations.grad, grads[1], rtol=1e-9, atol=1e-12)


def test_deformed_vertices_equal_the_graph() -> None:
    m = trimesh.creation.icosphere(subdivisions=3)
    graph = DeformationGraph(torch.tensor(m.vertices), torch.tensor(m.faces), node_spacing=0.2)
    with torch.no_grad():
        graph.rotations.copy_(0.5 * torch.randn(graph.rotations.shape, dtype=torch.float64))
        graph.translations.copy_(torch.randn(graph.translations.shape, dtype=torch.float64))
    torch.testing.assert_close(deformed_vertices(graph), graph().detach(), rtol=0, atol=1e-14)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_farthest_point_nodes_in_cpp_equal_the_torch_loop(monkeypatch: pytest.MonkeyPatch, dtype: torch.dtype) -> None:
    from torchmeshmetric.registration import deformation_graph, farthest_point_nodes

    g = torch.Generator().manual_seed(2)
    points = torch.rand(3000, 3, generator=g, dtype=dtype).mul(4).round()  # a lattice: many equal distances
    points = torch.cat([points, torch.rand(2000, 3, generator=g, dtype=dtype)])
    fast = farthest_point_nodes(points, 0.3)
    monkeypatch.setattr(deformation_graph, "bvh_ready", lambda: False)
    assert torch.equal(fast, farthest_point_nodes(points, 0.3))
