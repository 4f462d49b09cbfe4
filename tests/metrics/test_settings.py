"""Two configurations of one metric class never merge (review H, findings 2 and 3).

torchmetrics' ``merge_state`` checks the class of an incoming metric, not its options: it pooled exact and sampled
distances into one set of ``MeshSurfaceDistance``, and ``TemporalConsistency`` dropped the sets one configuration has
and the other lacks (or printed every tensor of the incoming states, the other way round).
"""

from __future__ import annotations

from typing import Any

import pytest
import torch
import trimesh
from torchmetrics import Metric

from tests.evaluation.eval_helpers import TranslationRegister, sphere
from torchmeshmetric.evaluation import TemporalConsistency
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


def _temporal(**kwargs: Any) -> TemporalConsistency:
    """A metric of one update on translated spheres (frames 0 and 1), with ``kwargs``."""
    metric = TemporalConsistency(registration_fn=TranslationRegister(), **kwargs)
    original = [sphere(2, offset=(0.1 * k, 0, 0)) for k in range(2)]
    simplified = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(2)]
    flicker = {"simplified_k_minus_1": simplified[0]} if kwargs.get("flicker") else {}
    metric.update(simplified[1], original[1], original[0], **flicker)
    return metric


def _shown(**kwargs: Any) -> str:
    sets = {"two_sided": True, "flicker": False, **kwargs}
    return (
        f"TemporalConsistency(two_sided={sets['two_sided']}, flicker={sets['flicker']}, "
        "registration_fn='tests.evaluation.eval_helpers.TranslationRegister', registration_options={})"
    )


@pytest.mark.parametrize(
    ("into", "incoming", "found"),
    [
        ({"two_sided": False}, {}, "unknown 8 (reverse_surface_k_minus_1_moments, "),  # dropped in silence
        ({}, {"two_sided": False}, "missing 8 (reverse_surface_k_minus_1_moments, "),  # 9.7 kB of tensors
        ({}, {"flicker": True}, "unknown 4 (flicker_moments, flicker_values, "),  # dropped in silence
        ({"flicker": True}, {}, "missing 4 (flicker_moments, flicker_values, "),  # 9.7 kB of tensors
    ],
)
def test_temporal_consistency_refuses_other_sets_both_ways(into, incoming, found):
    target, other = _temporal(**into), _temporal(**incoming)
    message = _refused(target, other)
    assert message == (
        f"incoming_state: {_shown(**incoming)} cannot merge into {_shown(**into)}: their states hold different "
        "measurements; merge metrics built with the same options"
    )
    # As a dict: named by the states it lacks or has too many of, in a line (no tensor printed).
    message = _refused(target, other.metric_state)
    assert message.startswith(f"incoming_state: expected the states of {_shown(**into)}, found {found}")
    assert len(message) < 400
    same = _temporal(**into)
    target.merge_state(same)  # the same sets still merge: every set holds both updates' distances
    alone = _temporal(**into).compute()
    assert target.compute()["vertex_k"]["count"].item() == 2 * alone["vertex_k"]["count"].item()
    assert target.compute()["vertex_k"]["ave"].item() == pytest.approx(alone["vertex_k"]["ave"].item(), rel=1e-12)


def test_temporal_consistency_refuses_other_registrations():
    default = TemporalConsistency()
    quick = TemporalConsistency(registration_options={"num_points": 500})
    assert (
        "registration_options={'num_points': 500}) cannot merge into TemporalConsistency(two_sided=True, "
        "flicker=False, registration_fn=None, registration_options={})" in _refused(default, quick)
    )
    assert "registration_fn=None" in _refused(_temporal(), default)
