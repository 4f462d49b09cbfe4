"""Differentiable MPEG terms: values equal the exact comparison, gradients equal finite differences (float64)."""

from __future__ import annotations

import pytest
import torch
import trimesh

from torchmeshmetric.mpeg import PointCloud, grid_sample, mpeg_compare
from torchmeshmetric.mpeg.comparison.losses import (
    MpegGeometryLoss,
    differentiable_grid_sample,
    mpeg_geometry_loss,
    mpeg_psnr_from_mse,
    point_to_plane_mse,
    point_to_point_mse,
)


def _clouds(n: int, dtype: torch.dtype, device: str) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(0)
    ref = torch.rand(n, 3, generator=g)
    dis = ref[: n - 7] + 0.02 * torch.randn(n - 7, 3, generator=g)
    nr = torch.nn.functional.normalize(torch.randn(n, 3, generator=g), dim=1)
    nd = torch.nn.functional.normalize(torch.randn(n - 7, 3, generator=g), dim=1)
    return tuple(x.to(device=device, dtype=dtype) for x in (ref, dis, nr, nd))  # type: ignore[return-value]


def test_values_equal_exact_comparison(device: str, dtype: torch.dtype) -> None:
    ref, dis, nr, nd = _clouds(300, dtype, device)
    exact = mpeg_compare(
        PointCloud(ref.float().cpu(), nr.float().cpu()), PointCloud(dis.float().cpu(), nd.float().cpu())
    )
    rtol = 1e-5 if dtype == torch.float32 else 1e-6  # exact path: float32 inputs; random clouds have no ties
    r64, d64 = ref.float().double(), dis.float().double()
    assert point_to_point_mse(r64, d64).item() == pytest.approx(exact.ref_to_dis.d1_mse, rel=1e-9)
    assert point_to_point_mse(ref, dis).item() == pytest.approx(exact.ref_to_dis.d1_mse, rel=rtol)
    assert point_to_point_mse(dis, ref).item() == pytest.approx(exact.dis_to_ref.d1_mse, rel=rtol)
    assert point_to_plane_mse(ref, dis, nd).item() == pytest.approx(exact.ref_to_dis.d2_mse, rel=rtol)
    assert point_to_plane_mse(dis, ref, nr).item() == pytest.approx(exact.dis_to_ref.d2_mse, rel=rtol)
    d2 = mpeg_geometry_loss(dis, ref, term="d2", ref_normals=nr, dis_normals=nd)
    assert d2.item() == pytest.approx(exact.symmetric.d2_mse, rel=rtol)
    assert mpeg_psnr_from_mse(d2, exact.peak).item() == pytest.approx(exact.symmetric.d2_psnr, abs=1e-4)


def test_gradients_match_finite_differences(device: str) -> None:
    ref, dis, nr, nd = _clouds(40, torch.float64, device)
    dis = dis.clone().requires_grad_(True)
    assert torch.autograd.gradcheck(lambda d: mpeg_geometry_loss(d, ref, reduction="mean"), (dis,))
    assert torch.autograd.gradcheck(lambda d: point_to_point_mse(d, ref), (dis,))
    assert torch.autograd.gradcheck(lambda d: point_to_plane_mse(ref, d, nd), (dis,))
    assert torch.autograd.gradcheck(
        lambda d: mpeg_geometry_loss(d, ref, term="d2", ref_normals=nr, dis_normals=nd), (dis,)
    )


def test_module_equals_function() -> None:
    ref, dis, nr, nd = _clouds(50, torch.float32, "cpu")
    assert MpegGeometryLoss("d2", "mean")(dis, ref, nr, nd).item() == pytest.approx(
        mpeg_geometry_loss(dis, ref, term="d2", ref_normals=nr, dis_normals=nd, reduction="mean").item()
    )
    with pytest.raises(ValueError, match="term"):
        MpegGeometryLoss("d3")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="D2 needs the normals"):
        mpeg_geometry_loss(dis, ref, term="d2")


def _sphere() -> trimesh.Trimesh:
    m = trimesh.creation.icosphere(1)
    m.apply_transform(trimesh.transformations.rotation_matrix(0.3, [1, 2, 3]))
    return m


def test_differentiable_grid_sample_values(device: str, dtype: torch.dtype) -> None:
    m = _sphere()
    verts = torch.tensor(m.vertices, dtype=torch.float32)
    faces = torch.tensor(m.faces)
    exact = grid_sample((verts, faces), 24)
    pts, nrm = differentiable_grid_sample(verts.to(device, dtype), faces.to(device), 24)
    assert pts.shape == exact.points.shape
    assert exact.normals is not None
    torch.testing.assert_close(pts.cpu().float(), exact.points, atol=3e-6, rtol=0)
    torch.testing.assert_close(nrm.cpu().float(), exact.normals, atol=3e-6, rtol=0)


def test_differentiable_grid_sample_gradcheck() -> None:
    m = _sphere()
    verts = torch.tensor(m.vertices, dtype=torch.float64, requires_grad=True)
    faces = torch.tensor(m.faces)
    ref = torch.tensor(m.vertices, dtype=torch.float64) * 1.05
    box = ([-1.2] * 3, [1.2] * 3)  # fixed box: the grid does not move with the vertices

    def loss(v: torch.Tensor) -> torch.Tensor:
        p, n = differentiable_grid_sample(v, faces, 12, box=box)
        return point_to_point_mse(p, ref) + point_to_plane_mse(ref, p, n)

    assert torch.autograd.gradcheck(loss, (verts,), eps=1e-7, atol=1e-5)
