"""Review D, findings 1-2: the Danskin backward of the surface losses on the surface and far from the origin."""

from __future__ import annotations

import pytest
import torch
import trimesh

from torchmeshmetric import MeshIndex, point_mesh_distance
from torchmeshmetric.kernels.danskin import surface_distances
from torchmeshmetric.metrics import mesh_surface_distance_loss


def _danskin_grads(points, verts, faces):
    p = points.clone().requires_grad_()
    v = verts.clone().requires_grad_()
    d = surface_distances(p, v, faces, MeshIndex(verts, faces), torch.tensor([points.shape[0]]))
    d.sum().backward()
    return d.detach(), p.grad, v.grad


def _autograd_point_grads(points, verts, faces):
    p = points.clone().requires_grad_()
    point_mesh_distance(p, verts, faces).dists.sum().backward()
    return p.grad


def _sphere(dtype):
    s = trimesh.creation.icosphere(subdivisions=2)
    return torch.tensor(s.vertices, dtype=dtype), torch.tensor(s.faces)


def _on_surface(verts, faces):
    """Points on the surface (to the rounding of their coordinates): vertices, edge midpoints, face centroids."""
    tri = verts[faces]
    return torch.cat([verts, 0.5 * (tri[:, 0] + tri[:, 1]), tri.mean(1)])


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_points_on_the_surface_get_the_subgradient_0_as_autograd_gives(dtype):
    # A point on a face has a computed distance at the rounding level (1e-17 in float64) and a rounding-noise
    # direction: the old backward returned that direction as a unit gradient (0.47 along the plane z = 0 here, 1.0
    # on the sphere's centroids) where autograd gives 0.
    square_v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=dtype)
    square_f = torch.tensor([[0, 1, 2], [0, 2, 3]])
    inside = torch.tensor([[0.2, 0.3, 0.0], [0.7, 0.1, 0.0], [0.3, 0.6, 0.0]], dtype=dtype)
    for verts, faces, points in (
        (square_v, square_f, torch.cat([inside, _on_surface(square_v, square_f)])),
        (*_sphere(dtype), _on_surface(*_sphere(dtype))),
    ):
        d, gp, gv = _danskin_grads(points, verts, faces)
        assert float(d.max()) < 1e-6  # on the surface, to rounding
        assert torch.equal(gp, torch.zeros_like(gp))
        assert torch.equal(gv, torch.zeros_like(gv))
    # Autograd through point_mesh_distance at the points inside the square's faces: 0 as well.
    assert torch.equal(_autograd_point_grads(inside, square_v, square_f), torch.zeros_like(inside))


def test_points_near_the_surface_match_autograd_and_central_differences():
    # Just off the sphere (along each face's normal, at 1e-3 and 1e-9 of its unit size), float64: the gradient is
    # the unit normal, as autograd and float64 central differences (step h / 2: the distance is linear along the
    # normal there, so the differences are exact up to rounding) give. Measured, max abs: at h = 1e-3 Danskin vs
    # autograd 9.5e-14, vs the normal 9.5e-14, vs central differences 3.8e-13; at h = 1e-9 (the closest point's
    # rounding, 1e-16, over the distance) 9.7e-8, 9.7e-8, 3.3e-7. Asserted: 1e-12 and 1e-6.
    verts, faces = _sphere(torch.float64)
    tri = verts[faces]
    n = torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n = n / n.norm(dim=1, keepdim=True)
    for h, tol in ((1e-3, 1e-12), (1e-9, 1e-6)):
        for sign in (1.0, -1.0):
            points = tri.mean(1) + sign * h * n
            d, gp, _ = _danskin_grads(points, verts, faces)
            torch.testing.assert_close(d, torch.full_like(d, h), rtol=1e-6, atol=0)  # measured 2.5e-13 / 2.1e-7
            torch.testing.assert_close(gp, _autograd_point_grads(points, verts, faces), rtol=0, atol=tol)
            torch.testing.assert_close(gp, sign * n, rtol=0, atol=tol)
            step = 0.5 * h
            central = torch.stack(
                [
                    (
                        point_mesh_distance(points + step * e, verts, faces).dists
                        - point_mesh_distance(points - step * e, verts, faces).dists
                    )
                    / (2 * step)
                    for e in torch.eye(3, dtype=torch.float64)
                ],
                dim=1,
            )
            torch.testing.assert_close(gp, central, rtol=0, atol=tol)


def test_float32_gradient_far_from_the_origin_keeps_its_accuracy():
    # A float32 sphere at 1e5, points 1 % outside. The old backward took p - c in world coordinates (rounded at
    # 1e5: ulp 0.0078) over a distance of the centred frame (~1e-2): 0.226 off float64 autograd. Measured now:
    # max |grad - float64 grad| 3.7e-6 (autograd in float32: 3.2e-7); times the distance 4.0e-8 = 0.67 float32 eps,
    # i.e. the rounding of the centred closest point (unit coordinates) over the distance: asserted <= 2 eps.
    verts0, faces = _sphere(torch.float64)
    for off in (0.0, 1e4, 1e5):
        verts = (verts0 + off).float()
        points = (verts0[:20] * 1.01 + off).float()
        p64 = points.double().requires_grad_()
        d64 = point_mesh_distance(p64, verts.double(), faces).dists
        d64.sum().backward()
        _, gp, _ = _danskin_grads(points, verts, faces)
        err = (gp.double() - p64.grad).norm(dim=1)
        assert float((err * d64.detach()).max()) <= 2 * torch.finfo(torch.float32).eps


def test_public_loss_far_from_the_origin_float32_matches_float64():
    # mesh_surface_distance_loss of a sphere 1 % larger than a reference at 1e5: per-vertex gradient norms were
    # 0.00617 to 0.00716 in float32 (16 % off) against 0.0061728395 in float64. Measured now: 1.5e-7 relative.
    s = trimesh.creation.icosphere(subdivisions=2)
    verts0, faces = torch.tensor(s.vertices), torch.tensor(s.faces)
    ref = (verts0 + 1e5).float()
    simp = (verts0 * 1.01 + 1e5).float()
    norms = {}
    for dt in (torch.float32, torch.float64):
        v = simp.to(dt).clone().requires_grad_()
        mesh_surface_distance_loss((v, faces), (ref.to(dt), faces), two_sided=False, power=1).backward()
        norms[dt] = v.grad.norm(dim=1).double()
    torch.testing.assert_close(norms[torch.float32], norms[torch.float64], rtol=1e-6, atol=0)


def test_small_real_distances_keep_their_gradient():
    # Found by review (2026-12-07): the on-surface floor was 64 ulps of the whole mesh's largest centred coordinate,
    # so a float32 point 3e-6 above a unit triangle (7.6e-6 floor) and one 2e-4 above a 0.01 triangle beside a
    # 100-unit plane (4e-4 floor) got gradient 0 where autograd gives the unit normal. The floor is now 8 ulps of
    # the point's and its face's own coordinates: 9.5e-7 and 1.2e-8 here.
    tri_v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    tri_f = torch.tensor([[0, 1, 2]])
    p = torch.tensor([[0.25, 0.25, 3e-6]])
    _, gp, _ = _danskin_grads(p, tri_v, tri_f)
    assert torch.equal(gp, torch.tensor([[0.0, 0.0, 1.0]]))
    plane_v = torch.tensor([[-100.0, -100, -1], [100, -100, -1], [100, 100, -1], [-100, 100, -1]])
    small_v = torch.tensor([[0.0, 0, 0], [0.01, 0, 0], [0, 0.01, 0]])
    verts = torch.cat([plane_v, small_v])
    faces = torch.tensor([[0, 1, 2], [0, 2, 3], [4, 5, 6]])
    p = torch.tensor([[0.0025, 0.0025, 2e-4]])
    d, gp, gv = _danskin_grads(p, verts, faces)
    assert float(d) == pytest.approx(2e-4, rel=1e-3)
    torch.testing.assert_close(gp, _autograd_point_grads(p, verts, faces), rtol=0, atol=1e-6)
    assert float(gp[0, 2]) == pytest.approx(1.0, abs=1e-6)
    assert float(gv[4:].sum(0)[2]) == pytest.approx(-1.0, abs=1e-6)  # the small face's corners take it all
