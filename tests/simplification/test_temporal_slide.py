"""TemporalSlide: its gates, its exact end points and its gradients."""

import pytest
import torch
import trimesh

from torchmeshmetric import Mesh, as_mesh, point_mesh_distance
from torchmeshmetric.simplification import TemporalSlide
from torchmeshmetric.simplification.temporal_slide import vertex_normals_and_scale


@pytest.fixture(scope="module")
def pair():
    """A coarse sphere and another tessellation of a slightly larger, shifted sphere (the warped previous frame)."""
    a = as_mesh(trimesh.creation.icosphere(subdivisions=2)).to(dtype=torch.float64)
    b = as_mesh(trimesh.creation.uv_sphere(count=[16, 16])).to(dtype=torch.float64)
    return a, Mesh(b.verts * 1.02 + torch.tensor([0.01, 0.0, 0.0], dtype=torch.float64), b.faces)


def _with_gates(tangential: float, normal: float) -> TemporalSlide:
    slide = TemporalSlide(across=True).double()
    with torch.no_grad():
        slide.net[-1].bias.copy_(torch.tensor([tangential, normal], dtype=torch.float64))
    return slide


def test_starts_at_its_initial_gate():
    feats = torch.randn(7, 4, dtype=torch.float64)
    for across, width in ((True, 2), (False, 1)):
        slide = TemporalSlide(initial_gate=0.25, across=across).double()
        assert torch.allclose(slide.gates(feats), torch.full((7, width), 0.25, dtype=torch.float64), atol=1e-15)


def test_full_gates_copy_the_closest_points_and_zero_gates_keep_the_vertices(pair):
    a, b = pair
    closest = point_mesh_distance(a.verts, b).closest
    assert torch.allclose(_with_gates(40.0, 40.0)(a, b), closest, atol=1e-15)  # sigmoid(40) == 1 in float64
    assert torch.equal(_with_gates(-800.0, -800.0)(a, b), a.verts)  # sigmoid(-800) == 0


def test_the_tangential_gate_moves_along_the_surface_only(pair):
    a, b = pair
    normals, _, _ = vertex_normals_and_scale(a.verts, a.faces)
    moved = (_with_gates(40.0, -800.0)(a, b) - a.verts).detach()
    assert float((moved * normals).sum(1).abs().max()) < 1e-15
    assert float(moved.norm(dim=1).max()) > 1e-3  # and it moves: the tessellations differ


def test_the_default_slides_along_the_surface_only(pair):
    a, b = pair
    slide = TemporalSlide().double()
    with torch.no_grad():
        slide.net[-1].bias.fill_(40.0)
    normals, _, _ = vertex_normals_and_scale(a.verts, a.faces)
    moved = (slide(a, b) - a.verts).detach()
    assert float((moved * normals).sum(1).abs().max()) < 1e-15
    assert torch.allclose(moved, (_with_gates(40.0, -800.0)(a, b) - a.verts).detach(), atol=1e-15)


def test_gradients_reach_the_parameters_and_the_previous_frame(pair):
    a, b = pair
    prev = b.verts.clone().requires_grad_(True)
    slide = TemporalSlide(initial_gate=0.5, across=True).double()
    out = slide(a, Mesh(prev, b.faces))
    point_mesh_distance(out, b).dists.sum().backward()
    grads = [p.grad for p in slide.parameters()] + [prev.grad]
    assert all(g is not None and bool(torch.isfinite(g).all()) for g in grads)
    assert float(slide.net[-1].bias.grad.abs().sum()) > 0 and float(prev.grad.abs().sum()) > 0


def test_bad_initial_gate():
    with pytest.raises(ValueError, match="initial_gate"):
        TemporalSlide(initial_gate=1.0)
