"""The dtype rule (docs/concepts.md, *Precision: one dtype rule*) over every public metric, loss and set function.

{float32, float64} x {tensor pair, ``Mesh``, trimesh} for the simplified and the reference x {one-, two-sided}: the
value comes back in the promoted dtype of the two meshes (metrics: float64 statistics, always), equal bit for bit to
the same entry on the inputs widened to float64 whenever a float64 input makes the computation float64 (nothing is
rounded), within a float32 tolerance otherwise; each tensor input's gradient comes back in its own dtype, and a
float32 gradient is the float64 one rounded once.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
import torch
import trimesh
from torch import Tensor

from torchmeshmetric import Mesh
from torchmeshmetric.metrics import (
    DistanceStatisticsMetric,
    MeshSurfaceDistance,
    MeshSurfaceDistanceLoss,
    NearestVertexDistance,
    NearestVertexDistanceLoss,
    TemporalConsistencyLoss,
    mesh_surface_distance_loss,
    mesh_surface_distance_sets,
    nearest_vertex_distance_loss,
    nearest_vertex_distance_sets,
    temporal_consistency_loss,
)

F32, F64 = torch.float32, torch.float64
# Each side: a tensor pair or a Mesh of either dtype, or a trimesh (always float64, trimesh's own dtype).
FORMS = ("pair32", "pair64", "Mesh32", "Mesh64", "trimesh")

# All-float32 computations against the float64 computation of the same (float32) inputs. Measured on these meshes
# (bounding-box diagonal 3.81; 2026-12-04): the largest difference over every entry, both sidednesses and the
# temporal loss is 0.24 x float32's eps x the diagonal (mesh_surface_distance_sets, two-sided, one distance); the
# tolerance is twice that.
F32_TOL = 2 * 0.24 * torch.finfo(F32).eps * 3.81


def _base() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A coarse, deformed sphere (the "simplified") and a finer unit sphere (the reference), as float64 arrays."""
    coarse = trimesh.creation.icosphere(subdivisions=1)
    v = coarse.vertices * (1.1 + 0.05 * np.sin(3 * coarse.vertices[:, :1])) + [0.03, -0.02, 0.01]
    fine = trimesh.creation.icosphere(subdivisions=2)
    return v, coarse.faces, fine.vertices, fine.faces


SIMP_V, SIMP_F, REF_V, REF_F = _base()


def _dtype(form: str) -> torch.dtype:
    return F32 if form.endswith("32") else F64


def _make(form: str, verts: np.ndarray, faces: np.ndarray, widened: bool = False) -> tuple[Any, Tensor | None]:
    """The mesh in ``form`` and its vertex tensor (``None`` for a trimesh: nothing to differentiate).

    ``widened``: the same values (float32 ones widened, exactly) as a float64 pair, the float64 computation's input.
    """
    if widened:
        v = torch.tensor(verts, dtype=_dtype(form)).to(F64).requires_grad_(True)
        return (v, torch.tensor(faces)), v
    if form == "trimesh":
        return trimesh.Trimesh(verts, faces, process=False), None
    v = torch.tensor(verts, dtype=_dtype(form), requires_grad=True)
    f = torch.tensor(faces)
    return ((v, f) if form.startswith("pair") else Mesh(v, f)), v


def _sets(fn: Callable[..., Any]) -> Callable[[Any, Any, bool], Tensor]:
    def run(s: Any, r: Any, two_sided: bool) -> Tensor:
        d = fn(s, r, two_sided=two_sided, detach_reference=False)
        return d.forward if d.reverse is None else torch.cat([d.forward, d.reverse])

    return run


def _metric(cls: type) -> Callable[[Any, Any, bool], Tensor]:
    def run(s: Any, r: Any, two_sided: bool) -> Tensor:
        metric = cls(two_sided=two_sided)
        metric.update(s, r)
        out = metric.compute()
        keys = ("ave", "max", "reverse_ave", "reverse_max") if two_sided else ("ave", "max")
        return torch.stack([out[k] for k in keys])

    return run


def _module(cls: type) -> Callable[[Any, Any, bool], Tensor]:
    def run(s: Any, r: Any, two_sided: bool) -> Tensor:
        loss = cls(power=2, two_sided=two_sided, detach_reference=False)
        first = loss(s, r)
        with torch.no_grad():  # a second call finds the reference's index in the module's cache: same value
            assert torch.equal(loss(s, r), first.detach())
        return first

    return run


ENTRIES: dict[str, tuple[Callable[[Any, Any, bool], Tensor], bool]] = {
    # name: (entry, differentiable)
    "mesh_surface_distance_loss": (
        lambda s, r, two: mesh_surface_distance_loss(s, r, two_sided=two, detach_reference=False),
        True,
    ),
    "nearest_vertex_distance_loss": (
        lambda s, r, two: nearest_vertex_distance_loss(s, r, two_sided=two, detach_reference=False),
        True,
    ),
    "MeshSurfaceDistanceLoss": (_module(MeshSurfaceDistanceLoss), True),
    "NearestVertexDistanceLoss": (_module(NearestVertexDistanceLoss), True),
    "mesh_surface_distance_sets": (_sets(mesh_surface_distance_sets), True),
    "nearest_vertex_distance_sets": (_sets(nearest_vertex_distance_sets), True),
    "MeshSurfaceDistance": (_metric(MeshSurfaceDistance), False),
    "NearestVertexDistance": (_metric(NearestVertexDistance), False),
}


def _check(value: Tensor, expected: Tensor, computed_in: torch.dtype) -> None:
    if computed_in == F64:  # the float32 inputs were widened exactly: the same float64 computation, bit for bit
        assert torch.equal(value.to(F64), expected), (value, expected)
    else:
        torch.testing.assert_close(value.to(F64), expected, rtol=0, atol=F32_TOL)


@pytest.mark.parametrize("two_sided", [False, True], ids=["one-sided", "two-sided"])
@pytest.mark.parametrize("ref_form", FORMS)
@pytest.mark.parametrize("simp_form", FORMS)
@pytest.mark.parametrize("entry", list(ENTRIES))
def test_dtype_rule(entry: str, simp_form: str, ref_form: str, two_sided: bool) -> None:
    fn, differentiable = ENTRIES[entry]
    simplified, sv = _make(simp_form, SIMP_V, SIMP_F)
    reference, rv = _make(ref_form, REF_V, REF_F)
    promoted = torch.promote_types(_dtype(simp_form), _dtype(ref_form))

    value = fn(simplified, reference, two_sided)
    assert value.dtype == (promoted if differentiable else F64)

    s64, sv64 = _make(simp_form, SIMP_V, SIMP_F, widened=True)
    r64, rv64 = _make(ref_form, REF_V, REF_F, widened=True)
    expected = fn(s64, r64, two_sided)
    _check(value.detach(), expected.detach(), promoted)
    if not differentiable or (sv is None and rv is None):  # a metric, or two trimeshes: nothing to differentiate
        return
    value.sum().backward()
    expected.sum().backward()
    _check_grads([sv, rv], [sv64, rv64], promoted)


def _check_grads(given: list[Tensor | None], widened: list[Tensor | None], computed_in: torch.dtype) -> None:
    """Each tensor input's gradient in its own dtype; with a float64 computation, the float64 one rounded once."""
    for v, v64 in zip(given, widened, strict=True):
        if v is None:  # a trimesh: nothing to differentiate
            continue
        assert v.grad is not None and v.grad.dtype == v.dtype
        if computed_in == F64:
            assert v64 is not None and v64.grad is not None
            assert torch.equal(v.grad, v64.grad.to(v.dtype))


@pytest.mark.parametrize("dtype", [F32, F64])
def test_distance_statistics_metric_accumulates_either_dtype_in_float64(dtype: torch.dtype) -> None:
    dists = torch.tensor([0.1, 0.25, 1.0 / 3.0], dtype=dtype)
    metric = DistanceStatisticsMetric(two_sided=True)
    metric.update(dists, dists[:2].to(F64))
    out = metric.compute()
    assert all(v.dtype == F64 for v in out.values())
    widened = dists.to(F64)
    assert out["ave"].item() == pytest.approx(widened.mean().item(), rel=1e-15)
    assert out["reverse_max"].item() == widened[1].item()


@pytest.mark.parametrize("two_sided", [False, True], ids=["one-sided", "two-sided"])
@pytest.mark.parametrize("original_form", FORMS)
@pytest.mark.parametrize("simplified_form", ["pair32", "pair64", "Mesh32", "Mesh64"])
@pytest.mark.parametrize("entry", ["temporal_consistency_loss", "TemporalConsistencyLoss"])
def test_temporal_consistency_loss_dtype_rule(
    entry: str, simplified_form: str, original_form: str, two_sided: bool
) -> None:
    """The four frames of any dtypes: the loss in their promoted dtype, each frame's gradient in its own.

    The registration is given as the registered mesh (frame k-1 shifted onto frame k): its piecewise-linear warp
    moves simplified frame k-1, and no registration is computed.
    """

    def run(widened: bool) -> tuple[Tensor, list[Tensor | None]]:
        shift = np.array([0.05, 0.0, 0.0])
        s_k, sv_k = _make(simplified_form, SIMP_V + shift, SIMP_F, widened)
        s_km1, sv_km1 = _make(simplified_form, SIMP_V * 0.98, SIMP_F, widened)
        o_k, _ = _make(original_form, REF_V + shift, REF_F, widened)
        o_km1, _ = _make(original_form, REF_V, REF_F, widened)
        registered, _ = _make(original_form, REF_V + shift, REF_F, widened)
        options: dict[str, Any] = {"frame_weight": 0.5, "two_sided": two_sided}
        if entry == "TemporalConsistencyLoss":
            loss = TemporalConsistencyLoss(**options)(s_k, s_km1, o_k, o_km1, registered)
        else:
            loss = temporal_consistency_loss(s_k, s_km1, o_k, o_km1, registered, **options)
        loss.backward()
        return loss, [sv_k, sv_km1]

    promoted = torch.promote_types(_dtype(simplified_form), _dtype(original_form))
    loss, given = run(widened=False)
    assert loss.dtype == promoted
    expected, widened = run(widened=True)
    _check(loss.detach(), expected.detach(), promoted)
    _check_grads(given, widened, promoted)


@pytest.mark.parametrize("term", ["d1", "d2"])
@pytest.mark.parametrize("ref_dtype", [F32, F64])
@pytest.mark.parametrize("dis_dtype", [F32, F64])
def test_mpeg_geometry_loss_dtype_rule(dis_dtype: torch.dtype, ref_dtype: torch.dtype, term: str) -> None:
    """The MPEG geometry loss takes point clouds (tensors only): the same rule through nearest_vertex_distance."""
    from torchmeshmetric.mpeg import mpeg_geometry_loss

    def run(widened: bool) -> tuple[Tensor, Tensor]:
        def cloud(v: np.ndarray, dtype: torch.dtype) -> Tensor:
            t = torch.tensor(v, dtype=dtype)
            return t.to(F64) if widened else t

        dis = cloud(SIMP_V, dis_dtype).requires_grad_(True)
        ref = cloud(REF_V, ref_dtype)
        normals = {}
        if term == "d2":  # unit normals of spheres: the directions of the points
            normals = {
                "dis_normals": cloud(SIMP_V / np.linalg.norm(SIMP_V, axis=1, keepdims=True), dis_dtype),
                "ref_normals": cloud(REF_V / np.linalg.norm(REF_V, axis=1, keepdims=True), ref_dtype),
            }
        loss = mpeg_geometry_loss(dis, ref, term=term, **normals)
        loss.backward()
        return loss, dis

    promoted = torch.promote_types(dis_dtype, ref_dtype)
    loss, dis = run(widened=False)
    expected, dis64 = run(widened=True)
    assert loss.dtype == promoted
    _check(loss.detach(), expected.detach(), promoted)
    _check_grads([dis], [dis64], promoted)
