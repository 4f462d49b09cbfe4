"""Two configurations of one metric class never merge (review H, finding 3).

torchmetrics' ``merge_state`` checks the class of an incoming metric, not its options: it pooled exact and sampled
distances into one set of ``MeshSurfaceDistance``.
"""

from __future__ import annotations

from typing import Any

import pytest
import torch
import trimesh
from torchmetrics import Metric

from torchmeshmetric.metrics import MeshSurfaceDistance
from torchmeshmetric.mpeg import MpegPSNR


def _mesh(num_verts: int, num_faces: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    verts = torch.rand(num_verts, 3, generator=g, dtype=torch.float64)
    return verts, torch.randint(0, num_verts, (num_faces, 3), generator=g)


REFERENCE, SIMPLIFIED = _mesh(15, 20, 1), _mesh(10, 8, 2)


def _refused(into: Metric, incoming: dict[str, Any] | Metric) -> str:
    before = {k: v.clone() if isinstance(v, torch.Tensor) else list(v) for k, v in into.metric_state.items()}
    with pytest.raises(ValueError, match=r"^incoming_state: ") as raised:
        into.merge_state(incoming)
    for key, value in into.metric_state.items():  # refused before anything merged
        assert torch.equal(value, before[key]) if isinstance(value, torch.Tensor) else value == before[key], key
    return str(raised.value)


def test_merge_state_refuses_sampled_into_exact():
    # Accepted before: exact and sampled (over-estimated) distances pooled into one set of 20.
    exact = MeshSurfaceDistance()
    exact.update(SIMPLIFIED, REFERENCE)
    sampled = MeshSurfaceDistance(surface_samples=20)
    sampled.update(_mesh(10, 8, 3), REFERENCE)
    assert _refused(exact, sampled) == (
        "incoming_state: MeshSurfaceDistance(two_sided=False, exact_quantiles=True, surface_samples=20, seed=0) "
        "cannot merge into MeshSurfaceDistance(two_sided=False, exact_quantiles=True, surface_samples=None): their "
        "states hold different measurements; merge metrics built with the same options"
    )
    assert "surface_samples=None) cannot merge" in _refused(sampled, exact)
    assert "seed=1) cannot merge" in _refused(sampled, MeshSurfaceDistance(surface_samples=20, seed=1))
    same = MeshSurfaceDistance(surface_samples=20)
    same.update(SIMPLIFIED, REFERENCE)
    both = MeshSurfaceDistance(surface_samples=20)
    both.update(_mesh(10, 8, 3), REFERENCE)
    both.update(SIMPLIFIED, REFERENCE)
    sampled.merge_state(same)
    merged, expected = sampled.compute(), both.compute()
    assert merged["count"].item() == 20.0
    for key in ("ave", "max", "median", "var"):
        assert merged[key].item() == pytest.approx(expected[key].item(), rel=1e-12), key
    exact_seeds = MeshSurfaceDistance(seed=5)  # the exact distances read no seed: the same measurement
    exact_seeds.update(SIMPLIFIED, REFERENCE)
    exact.merge_state(exact_seeds)
    assert exact.compute()["count"].item() == 20.0


def test_merge_state_refuses_other_mpeg_sampling():
    sphere = trimesh.creation.icosphere(2)
    grid, mesh = MpegPSNR(grid_size=64), MpegPSNR(sampling="mesh")
    grid.update(sphere.copy().apply_scale(1.01), sphere)
    mesh.update(sphere.copy().apply_scale(1.02), sphere)
    assert _refused(grid, mesh).startswith(
        "incoming_state: MpegPSNR(sampling='mesh') cannot merge into MpegPSNR(sampling='grid', grid_size=64): "
    )
    assert "grid_size=64) cannot merge into MpegPSNR(sampling='grid', grid_size=128)" in _refused(
        MpegPSNR(grid_size=128), grid
    )
