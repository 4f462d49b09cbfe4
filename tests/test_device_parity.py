"""Every public tensor op on a device, in float32, against the same op on the CPU in float64 (issue 39).

Each test runs for ``device="cpu"`` everywhere (the float32-vs-float64 comparison on the CPU: the test's logic is
exercised without a GPU) and for ``device="cuda"`` where one is present (marked ``cuda``: ``pytest -m cuda`` selects
those, which ``tests/benchmarks/gpu_check.sh`` runs on the GPU).

Tolerance: float32 distances within ``1e-6 x`` the mesh's bounding-box diagonal of the float64 ones, the bound the
suite's CUDA tests already use (tests/kernels/test_point_triangle.py, test_accel_equality.py): a float32 distance
is computed from centred coordinates of magnitude <= the diagonal with a few dozen roundings of 2**-24 each
(~8 ulps of the diagonal, 5e-7). Gradients (unit directions ``(p - c) / d`` scaled by the reduction) within
``1e-4`` of their largest entry: the query points keep at least 0.1 of the diagonal from the surface, so a direction
carries a float32 error of ~1e-7 / 0.1 relative; points near the medial axis, where float32 may pick another
closest point at the same distance, are left out (``_points``), and the other meshes are turned off the bumpy
mesh's icosahedral symmetry (``_simplified``).
"""

from __future__ import annotations

import functools

import pytest
import torch
import trimesh

from torchmeshmetric import (
    DistanceAccumulator,
    Mesh,
    MeshIndex,
    MeshSurfaceDistance,
    NearestVertexDistance,
    closest_point_on_triangle,
    distance_statistics,
    kabsch_umeyama,
    mesh_surface_distance_loss,
    nearest_vertex_distance,
    nearest_vertex_distance_loss,
    point_mesh_distance,
    sample_surface,
    temporal_consistency_loss,
    vertex_set,
)

DIST_TOL = 1e-6  # x the bounding-box diagonal (see the module docstring)
GRAD_TOL = 1e-4  # x the largest gradient entry


def _sphere(subdivisions: int = 3, radius: float = 1.0) -> Mesh:
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return Mesh(torch.tensor(m.vertices, dtype=torch.float64), torch.tensor(m.faces))


@functools.cache
def _bumpy() -> Mesh:
    """An icosphere with a smooth bump field: faces of many sizes and orientations (no symmetric ties)."""
    m = _sphere(3)
    v = m.verts
    r = 1.0 + 0.15 * torch.sin(3 * v[:, 0]) * torch.cos(2 * v[:, 1]) + 0.1 * v[:, 2] ** 2
    return Mesh(v * r[:, None], m.faces)


@functools.cache
def _points(n: int, seed: int, mesh: Mesh | None = None) -> torch.Tensor:
    """Query points away from the bumpy surface (radius in [0.3, 0.6] or [1.6, 2.6]) with one clear closest face.

    Near the medial axis two faces are almost equally near and float32 may pick the other one (a different closest
    point and gradient, the same distance): points whose two nearest faces (float64) are within ``1e-4 x`` the
    diagonal of each other are dropped.
    """
    mesh = mesh if mesh is not None else _bumpy()
    g = torch.Generator().manual_seed(seed)
    d = torch.randn(n, 3, generator=g, dtype=torch.float64)
    d = d / d.norm(dim=1, keepdim=True)
    inner = torch.rand(n, generator=g) < 0.5
    r = torch.where(inner, 0.3 + 0.3 * torch.rand(n, generator=g), 1.6 + torch.rand(n, generator=g))
    p = d * r[:, None].to(torch.float64)
    a, b, c = (mesh.verts[mesh.faces[:, i]] for i in range(3))
    diag = float(mesh.bbox_diagonal())
    keep = []
    for q in p.split(128):
        r = closest_point_on_triangle(q[:, None], a, b, c)
        dist, best = r.sq_dists.sqrt(), r.sq_dists.argmin(dim=1)
        winner = r.closest[torch.arange(q.shape[0]), best]
        # Faces whose closest point is elsewhere (not the shared edge or corner of the winner) must be clearly farther.
        elsewhere = (r.closest - winner[:, None]).norm(dim=-1) > 1e-3 * diag
        rival = torch.where(elsewhere, dist, torch.inf).amin(dim=1)
        keep.append(rival - dist.amin(dim=1) > 1e-4 * diag)
    return p[torch.cat(keep)]


def _simplified(subdivisions: int, radius: float, angle: float) -> Mesh:
    """A coarse sphere around the bumpy one (radius >= 1.5: every distance >= 0.25), turned by a generic rotation.

    Unturned, its vertices and the bumpy mesh's lie on the same icosahedral directions, exactly on the bisectors
    between faces: exact ties that float32 and float64 break differently.
    """
    m = _sphere(subdivisions, radius)
    axis = torch.tensor([0.3, -0.5, 0.81], dtype=torch.float64)
    axis = axis / axis.norm()
    k = torch.tensor(
        [[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]], dtype=torch.float64
    )
    rot = torch.linalg.matrix_exp(angle * k)
    return Mesh(m.verts @ rot.T, m.faces)


def _f32(x: torch.Tensor, device: str) -> torch.Tensor:
    return x.to(device=device, dtype=torch.float32)


def _mesh32(m: Mesh, device: str) -> Mesh:
    return Mesh(_f32(m.verts, device), m.faces.to(device))


def _close(got: torch.Tensor, ref: torch.Tensor, atol: float) -> None:
    torch.testing.assert_close(got.detach().cpu().double(), ref.detach().cpu().double(), rtol=0, atol=atol)


def _grad_close(got: torch.Tensor, ref: torch.Tensor) -> None:
    _close(got, ref, GRAD_TOL * float(ref.abs().max()))


def test_closest_point_on_triangle(device: str) -> None:
    g = torch.Generator().manual_seed(1)
    p, a, b, c = (torch.randn(4000, 3, generator=g, dtype=torch.float64) for _ in range(4))
    ref = closest_point_on_triangle(p, a, b, c)
    got = closest_point_on_triangle(*(_f32(x, device) for x in (p, a, b, c)))
    assert got.closest.device.type == device
    scale = float(torch.stack([p, a, b, c]).abs().max())
    _close(got.closest, ref.closest, DIST_TOL * scale)
    _close(got.sq_dists.sqrt(), ref.sq_dists.sqrt(), DIST_TOL * scale)


def test_point_mesh_distance_values_and_gradients(device: str) -> None:
    m, p = _bumpy(), _points(1000, 2)
    diag = float(m.bbox_diagonal())
    p64, v64 = p.clone().requires_grad_(True), m.verts.clone().requires_grad_(True)
    ref = point_mesh_distance(p64, v64, m.faces)
    ref.dists.mean().backward()
    p32, v32 = _f32(p, device).requires_grad_(True), _f32(m.verts, device).requires_grad_(True)
    got = point_mesh_distance(p32, v32, m.faces.to(device))
    got.dists.mean().backward()
    assert got.dists.device.type == device and got.dists.dtype == torch.float32
    _close(got.dists, ref.dists, DIST_TOL * diag)
    _close(got.closest, ref.closest, DIST_TOL * diag)
    assert p32.grad is not None and v32.grad is not None and p64.grad is not None and v64.grad is not None
    _grad_close(p32.grad, p64.grad)
    _grad_close(v32.grad, v64.grad)


def test_mesh_index_query_and_refit(device: str) -> None:
    m, p = _bumpy(), _points(1000, 3)
    diag = float(m.bbox_diagonal())
    index64, index32 = MeshIndex(m), MeshIndex(_mesh32(m, device))
    _close(index32.point_mesh_distance(_f32(p, device)).dists, index64.point_mesh_distance(p).dists, DIST_TOL * diag)
    moved = m.verts * 1.05 + torch.tensor([0.01, -0.02, 0.03], dtype=torch.float64)
    index64.refit(moved)
    index32.refit(_f32(moved, device))
    _close(
        index32.point_mesh_distance(_f32(p, device)).dists, index64.point_mesh_distance(p).dists, 1.05 * DIST_TOL * diag
    )
    _close(
        index32.nearest_vertex_distance(_f32(p, device)).dists,
        index64.nearest_vertex_distance(p).dists,
        DIST_TOL * diag,
    )


def test_nearest_vertex_distance(device: str) -> None:
    m, p = _bumpy(), _points(1000, 4)
    ref = nearest_vertex_distance(p, m.verts)
    got = nearest_vertex_distance(_f32(p, device), _f32(m.verts, device))
    _close(got.dists, ref.dists, DIST_TOL * float(m.bbox_diagonal()))


def test_sample_surface_lies_on_the_surface(device: str) -> None:
    # Sampling draws from the device's generator (different streams): the samples are checked on the surface.
    m = _mesh32(_bumpy(), device)
    s = sample_surface(m, n=4000, generator=torch.Generator(device=device).manual_seed(5))
    assert s.points.device.type == device
    d = point_mesh_distance(s.points.double().cpu(), _bumpy())
    assert float(d.dists.max()) <= DIST_TOL * float(_bumpy().bbox_diagonal())


def test_vertex_set(device: str) -> None:
    m = _bumpy()
    faces = m.faces[m.faces.max(dim=1).values < m.num_verts - 5]  # the last vertices become unreferenced
    ref = vertex_set((m.verts, faces))
    got = vertex_set((_f32(m.verts, device), faces.to(device)))
    assert got.device.type == device
    _close(got, ref, 1e-7)


def test_distance_statistics_and_accumulator(device: str) -> None:
    g = torch.Generator().manual_seed(6)
    d64 = torch.rand(10_000, generator=g, dtype=torch.float64) ** 2
    d32 = _f32(d64, device)
    ref = distance_statistics(d32.double().cpu(), peak=2.0)  # statistics are float64 sums of the given values
    got = distance_statistics(d32, peak=2.0)
    acc = DistanceAccumulator()
    for chunk in d32.split(3000):
        acc.update(chunk)
    pooled = acc.compute(peak=2.0)
    for name in ("ave", "var", "mse", "rmse", "max", "min", "median", "p95", "p99", "psnr"):
        r = getattr(ref, name)
        torch.testing.assert_close(getattr(got, name).cpu(), r, rtol=1e-12, atol=0, msg=name)
        torch.testing.assert_close(getattr(pooled, name).cpu(), r, rtol=1e-12, atol=0, msg=name)


def test_metrics(device: str) -> None:
    ref_mesh, simp = _bumpy(), _simplified(1, 1.6, 0.3)
    diag = float(ref_mesh.bbox_diagonal())
    surface64, vertex64 = MeshSurfaceDistance(two_sided=True), NearestVertexDistance()
    surface64.update(simp, ref_mesh)
    vertex64.update(simp, ref_mesh)
    surface32, vertex32 = MeshSurfaceDistance(two_sided=True).to(device), NearestVertexDistance().to(device)
    surface32.update(_mesh32(simp, device), _mesh32(ref_mesh, device))
    vertex32.update(_mesh32(simp, device), _mesh32(ref_mesh, device))
    for m32, m64 in ((surface32, surface64), (vertex32, vertex64)):
        got, ref = m32.compute(), m64.compute()
        assert set(got) == set(ref)
        for k in ("ave", "max", "rmse", "median", "p95"):
            _close(got[k], ref[k], DIST_TOL * diag)
        assert int(got["count"]) == int(ref["count"])


@pytest.mark.parametrize("loss", [mesh_surface_distance_loss, nearest_vertex_distance_loss])
def test_distance_losses_and_gradients(device: str, loss) -> None:
    ref_mesh, simp = _bumpy(), _simplified(2, 1.6, 0.3)
    v64 = simp.verts.clone().requires_grad_(True)
    l64 = loss((v64, simp.faces), ref_mesh, power=2)
    l64.backward()
    v32 = _f32(simp.verts, device).requires_grad_(True)
    l32 = loss((v32, simp.faces.to(device)), _mesh32(ref_mesh, device), power=2)
    l32.backward()
    assert l32.device.type == device
    _close(l32, l64, 10 * DIST_TOL * float(l64.detach()))  # a mean of squares: float32 relative rounding of the sum
    assert v32.grad is not None and v64.grad is not None
    _grad_close(v32.grad, v64.grad)


def test_temporal_consistency_loss_and_gradients(device: str) -> None:
    orig_k, orig_km1 = _bumpy(), _sphere(3)
    s_k, s_km1 = _simplified(2, 1.6, 0.3), _simplified(2, 1.5, 0.7)

    def warp(p: torch.Tensor) -> torch.Tensor:  # a smooth map of frame k-1 onto frame k, differentiable
        return p * (1.02 + 0.01 * p[:, :1])

    a64, b64 = s_k.verts.clone().requires_grad_(True), s_km1.verts.clone().requires_grad_(True)
    l64 = temporal_consistency_loss((a64, s_k.faces), (b64, s_km1.faces), orig_k, orig_km1, warp)
    l64.backward()
    a32, b32 = _f32(s_k.verts, device).requires_grad_(True), _f32(s_km1.verts, device).requires_grad_(True)
    l32 = temporal_consistency_loss(
        (a32, s_k.faces.to(device)),
        (b32, s_km1.faces.to(device)),
        _mesh32(orig_k, device),
        _mesh32(orig_km1, device),
        warp,
    )
    l32.backward()
    assert l32.device.type == device
    _close(l32, l64, 4 * DIST_TOL * float(orig_k.bbox_diagonal()))  # four mean distances added
    for g32, g64 in ((a32.grad, a64.grad), (b32.grad, b64.grad)):
        assert g32 is not None and g64 is not None
        _grad_close(g32, g64)


def _rotation(angle: float) -> torch.Tensor:
    c, s = torch.cos(torch.tensor(angle, dtype=torch.float64)), torch.sin(torch.tensor(angle, dtype=torch.float64))
    return torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64)


def test_kabsch_umeyama(device: str) -> None:
    g = torch.Generator().manual_seed(7)
    src = torch.randn(500, 3, generator=g, dtype=torch.float64)
    rot, t = _rotation(0.4), torch.tensor([0.3, -0.2, 0.1], dtype=torch.float64)
    dst = 1.3 * src @ rot.T + t
    ref = kabsch_umeyama(src, dst, scale=True)
    got = kabsch_umeyama(_f32(src, device), _f32(dst, device), scale=True)
    for name in ("rotation", "translation", "scale"):
        _close(getattr(got, name), getattr(ref, name), 1e-5)  # a 3x3 SVD of float32 sums over 500 points
    _close(ref.rotation, rot, 1e-12)
