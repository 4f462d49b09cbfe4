import math

import numpy as np
import pytest
import torch
import trimesh

from tests.registration.gt_pairs import figure_sdf, mesh_level_set
from torchmeshmetric import DeviceError, EmptyInputError, NonFiniteError, ShapeError
from torchmeshmetric.data import add_capture_defects
from torchmeshmetric.registration import kabsch_umeyama, register_rigid


def _rotation(angle: float, axis) -> torch.Tensor:
    return torch.tensor(trimesh.transformations.rotation_matrix(angle, axis)[:3, :3])


def _asym_mesh() -> trimesh.Trimesh:
    # The stick-figure performer (no symmetry: the arms differ), ~700 vertices.
    v, f = mesh_level_set(figure_sdf, 0.07)
    return trimesh.Trimesh(v, f, process=False)


def test_kabsch_umeyama_exact_with_scale_and_weights():
    g = torch.Generator().manual_seed(0)
    src = torch.randn(50, 3, generator=g, dtype=torch.float64)
    R = _rotation(1.1, [1, 2, 3])
    dst = 1.7 * src @ R.T + torch.tensor([0.3, -2.0, 5.0], dtype=torch.float64)
    w = torch.rand(50, generator=g, dtype=torch.float64)
    dst[:5] += 100.0  # outliers with zero weight
    w[:5] = 0
    T = kabsch_umeyama(src, dst, w, scale=True)
    torch.testing.assert_close(T.rotation, R, atol=1e-12, rtol=0)
    assert abs(float(T.scale) - 1.7) < 1e-12
    torch.testing.assert_close(T.translation, torch.tensor([0.3, -2.0, 5.0], dtype=torch.float64), atol=1e-12, rtol=0)


def test_kabsch_never_returns_a_reflection():
    src = torch.randn(20, 3, dtype=torch.float64)
    dst = src * torch.tensor([1.0, 1.0, -1.0], dtype=torch.float64)  # a mirror image
    T = kabsch_umeyama(src, dst)
    assert float(torch.linalg.det(T.rotation)) == pytest.approx(1.0, abs=1e-12)


def test_register_rigid_point_to_point_converges_linearly():
    # Point-to-point ICP converges linearly (Besl & McKay): after 60 iterations the motion is recovered to 1e-3.
    m = _asym_mesh()
    R = _rotation(0.15, [0.2, 1.0, 0.4])
    v, f = torch.tensor(m.vertices), torch.tensor(m.faces)
    r = register_rigid((v, f), (v @ R.T, f), max_iterations=60)
    torch.testing.assert_close(r.rotation, R, atol=1e-3, rtol=0)
    assert float(r.rmse) < 2e-4


def test_register_rigid_recovers_known_motion():
    point_to_plane = True
    m = _asym_mesh()
    R = _rotation(0.35, [0.2, 1.0, 0.4])
    t = torch.tensor([0.1, -0.05, 0.08], dtype=torch.float64)
    v = torch.tensor(m.vertices)
    tgt = (v @ R.T + t, torch.tensor(m.faces))
    r = register_rigid((v, torch.tensor(m.faces)), tgt, point_to_plane=point_to_plane, max_iterations=60)
    assert r.converged
    torch.testing.assert_close(r.rotation, R, atol=1e-6, rtol=0)
    torch.testing.assert_close(r.translation, t, atol=1e-6, rtol=0)
    assert float(r.scale) == 1.0
    torch.testing.assert_close(r.verts, tgt[0], atol=1e-6, rtol=0)
    assert float(r.rmse) < 1e-6
    T = r.transform
    torch.testing.assert_close(T[:3, :3], R, atol=1e-6, rtol=0)


def test_register_rigid_with_scale_and_outliers():
    m = _asym_mesh()
    R = _rotation(-0.3, [1.0, 0.3, 0.0])
    v = torch.tensor(m.vertices)
    f = torch.tensor(m.faces)
    tv = 1.3 * v @ R.T + torch.tensor([0.2, 0.0, -0.1], dtype=torch.float64)
    # Outliers: a far-away blob added to the source (its vertices find no good match and get trimmed).
    blob = trimesh.creation.icosphere(subdivisions=1, radius=0.05)
    sv = torch.cat([v, torch.tensor(blob.vertices) + torch.tensor([3.0, 0.0, 0.0], dtype=torch.float64)])
    sf = torch.cat([f, torch.tensor(blob.faces) + v.shape[0]])
    r = register_rigid(
        (sv, sf), (tv, f), scale=True, point_to_plane=True, trim=0.85, max_iterations=80, align_centroids=False
    )
    torch.testing.assert_close(r.rotation, R, atol=1e-5, rtol=0)
    assert float(r.scale) == pytest.approx(1.3, abs=1e-5)
    torch.testing.assert_close(r.verts[: v.shape[0]], tv, atol=1e-5, rtol=0)


def test_register_rigid_on_capture_defects():
    m = _asym_mesh()
    d = add_capture_defects((m.vertices, m.faces), seed=1, normalize=False, shuffle=False)
    v, f = d.verts, d.faces
    R = _rotation(0.2, [0, 0, 1])
    r = register_rigid((v, f), (m.vertices @ R.numpy().T, m.faces), point_to_plane=True)
    assert r.converged
    torch.testing.assert_close(r.rotation, R, atol=1e-5, rtol=0)


def test_register_rigid_bad_inputs():
    m = trimesh.creation.box()
    v, f = torch.tensor(m.vertices), torch.tensor(m.faces)
    with pytest.raises(EmptyInputError, match="source"):
        register_rigid((v, f[:0]), (v, f))
    bad = v.clone()
    bad[0, 0] = math.nan
    with pytest.raises(NonFiniteError, match=r"target\.verts"):
        register_rigid((v, f), (bad, f))
    with pytest.raises(ShapeError, match=r"source\.verts"):
        register_rigid((v[:, :2], f), (v, f))
    with pytest.raises(ValueError, match="trim"):
        register_rigid((v, f), (v, f), trim=0.0)
    with pytest.raises(ShapeError, match="dst"):
        kabsch_umeyama(v, v[:3])
    if torch.cuda.is_available():
        with pytest.raises(DeviceError):
            register_rigid((v, f), (v.cuda(), f.cuda()))
    np.testing.assert_equal(True, True)


def _rotated_pair() -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(0)
    src = torch.randn(20, 3, dtype=torch.float64, generator=g)
    c, s = math.cos(0.7), math.sin(0.7)
    rot = torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    return src, 2.5 * src @ rot.T + 1.0, rot


@pytest.mark.parametrize(
    ("dtype", "factor"),
    [
        (torch.float64, 1e200),
        (torch.float64, 1e300),
        (torch.float64, 1e-200),
        (torch.float32, 1e20),
        (torch.float32, 1e-25),
    ],
)
def test_kabsch_umeyama_at_extreme_magnitudes(dtype, factor):
    # Review V, F7: the covariance was formed in the input's units (degree 2): float64 1e200 and float32 1e20 raised
    # torch's _LinAlgError from the SVD. The rotation is scale-free and the scale a ratio of the same units.
    src, dst, rot = _rotated_pair()
    got = kabsch_umeyama((src * factor).to(dtype), (dst * factor).to(dtype), scale=True)
    # Measured: float64 <= 3.3e-16, float32 <= 2.4e-7 (rotation), the same relative on scale and translation.
    tol = 64 * torch.finfo(dtype).eps
    assert float((got.rotation.double() - rot).abs().max()) <= tol
    assert float(got.scale) == pytest.approx(2.5, rel=tol)
    assert float((got.translation.double() / factor - 1.0).abs().max()) <= tol


def test_kabsch_umeyama_names_non_finite_and_negative_inputs():
    src, dst, _ = _rotated_pair()
    with pytest.raises(NonFiniteError, match="src"):
        kabsch_umeyama(src * float("nan"), dst)
    with pytest.raises(NonFiniteError, match="dst"):
        kabsch_umeyama(src, dst * float("inf"))
    with pytest.raises(NonFiniteError, match="weights"):
        kabsch_umeyama(src, dst, torch.full((20,), float("nan"), dtype=torch.float64))
    # Negative weights were clamped to 0 and then reported as "all zero".
    with pytest.raises(ValueError, match=r"weights: expected non-negative weights, found -1.0 at row 0"):
        kabsch_umeyama(src, dst, -torch.ones(20, dtype=torch.float64))
