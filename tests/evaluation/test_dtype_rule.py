"""The dtype rule in the evaluation (docs/concepts.md, *Precision*): ``evaluate_pair``, the flicker set and the
``TemporalConsistency`` metric measure frames of mixed dtypes in their promoted dtype, rounding nothing.

A float32 model's output against float64 originals (a trimesh) was measured with the originals rounded to float32;
now every set is the float64 computation on the same values, bit for bit.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric import Mesh
from torchmeshmetric.evaluation import TemporalConsistency, evaluate_pair, flatten_statistics

F32, F64 = torch.float32, torch.float64
FORMS = ("pair32", "pair64", "Mesh32", "Mesh64", "trimesh")
SHIFT = np.array([0.05, 0.0, 0.0])
_coarse, _fine = trimesh.creation.icosphere(subdivisions=1), trimesh.creation.icosphere(subdivisions=2)
SIMP_V = _coarse.vertices * (1.02 + 0.03 * np.sin(3 * _coarse.vertices[:, :1]))
SIMP_F, REF_V, REF_F = _coarse.faces, _fine.vertices, _fine.faces
# All-float32 against the float64 computation of the same values: within 2e-6 x the diagonal (~3.5) of a float64
# oracle, the kernels' measured float32 bound (docs/benchmarks.md, Exactness).
F32_TOL = 2e-6 * 3.5


def _dtype(form: str) -> torch.dtype:
    return F32 if form.endswith("32") else F64


def _make(form: str, verts: np.ndarray, faces: np.ndarray, widened: bool = False) -> Any:
    if widened:  # the same values as a float64 pair (float32 ones widened, exactly)
        return torch.tensor(verts, dtype=_dtype(form)).to(F64), torch.tensor(faces)
    if form == "trimesh":
        return trimesh.Trimesh(verts, faces, process=False)
    v, f = torch.tensor(verts, dtype=_dtype(form)), torch.tensor(faces)
    return (v, f) if form.startswith("pair") else Mesh(v, f)


def _frames(simplified_form: str, original_form: str, widened: bool) -> dict[str, Any]:
    return {
        "simplified_k": _make(simplified_form, SIMP_V + SHIFT, SIMP_F, widened),
        "simplified_k_minus_1": _make(simplified_form, SIMP_V * 0.98, SIMP_F, widened),
        "original_k": _make(original_form, REF_V + SHIFT, REF_F, widened),
        "original_k_minus_1": _make(original_form, REF_V, REF_F, widened),
    }


def _check(got: torch.Tensor, expected: torch.Tensor, computed_in: torch.dtype) -> None:
    if computed_in == F64:
        assert torch.equal(got.to(F64), expected)
    else:
        torch.testing.assert_close(got.to(F64), expected, rtol=0, atol=F32_TOL)


@pytest.mark.parametrize("original_form", FORMS)
@pytest.mark.parametrize("simplified_form", FORMS)
def test_evaluate_pair_measures_every_set_in_the_promoted_dtype(simplified_form: str, original_form: str) -> None:
    promoted = torch.promote_types(_dtype(simplified_form), _dtype(original_form))

    def run(widened: bool) -> Any:
        frames = _frames(simplified_form, original_form, widened)
        registered = _make(original_form, REF_V + SHIFT, REF_F, widened)  # frame k-1 registered onto frame k
        return evaluate_pair(
            frames["simplified_k"],
            frames["original_k"],
            frames["original_k_minus_1"],
            precomputed_registration=registered,
            simplified_k_minus_1=frames["simplified_k_minus_1"],
        )

    got, expected = run(widened=False), run(widened=True)
    assert set(got.distances) == set(expected.distances) and "flicker" in got.distances
    for sets, expected_sets in (
        (got.distances, expected.distances),
        (got.reverse_distances, expected.reverse_distances),
    ):
        for name, d in sets.items():
            assert d.dtype == promoted, name
            _check(d, expected_sets[name], promoted)


@pytest.mark.parametrize("original_form", ["pair32", "Mesh64", "trimesh"])
@pytest.mark.parametrize("simplified_form", ["pair32", "Mesh64"])
def test_temporal_consistency_metric_accumulates_mixed_frames_without_rounding(
    simplified_form: str, original_form: str
) -> None:
    promoted = torch.promote_types(_dtype(simplified_form), _dtype(original_form))

    def shift_register(source: Mesh, target: Mesh) -> Mesh:  # the exact registration of these frames
        return Mesh(source.verts + torch.tensor(SHIFT, dtype=source.dtype), source.faces)

    def run(widened: bool) -> dict[str, torch.Tensor]:
        metric = TemporalConsistency(registration_fn=shift_register, flicker=True)
        frames = _frames(simplified_form, original_form, widened)
        metric.update(
            frames["simplified_k"], frames["original_k"], frames["original_k_minus_1"], frames["simplified_k_minus_1"]
        )
        return flatten_statistics(metric.compute())

    got, expected = run(widened=False), run(widened=True)
    assert set(got) == set(expected)
    for key, value in got.items():
        assert value.dtype == F64, key  # the metric's statistics are float64 whatever the frames
        if promoted == F64:
            assert torch.equal(value, expected[key]), key
        else:  # all float32: every statistic within F32_TOL (measured: at most 3.4e-6, flicker/psnr in dB)
            torch.testing.assert_close(value, expected[key], rtol=0, atol=F32_TOL)
