"""The registration's target samples: faces drawn by index (not through an inverse CDF over the areas), area weights.

A rounding of the input moves an inverse CDF's steps, and a draw between the old and the new step went to the next
face in the list: anywhere on a captured frame (docs/registration.md, "Stability", item 8). Drawn by index, which face
a draw takes depends on the face count and the generator only.
"""

from __future__ import annotations

import math
import warnings

import pytest
import torch
import trimesh

from torchmeshmetric.data import add_capture_defects
from torchmeshmetric.registration import RegistrationWarning, register_nonrigid
from torchmeshmetric.registration.nonrigid import _target_samples


def _bumpy_sphere() -> tuple[torch.Tensor, torch.Tensor]:
    """An icosphere with vertices moved radially: faces of unequal areas (the largest 2.3x the smallest)."""
    m = trimesh.creation.icosphere(subdivisions=2)
    g = torch.Generator().manual_seed(1)
    v = torch.tensor(m.vertices) * (1 + 0.4 * torch.rand(len(m.vertices), 1, generator=g, dtype=torch.float64))
    return v, torch.tensor(m.faces)


def test_faces_depend_on_the_generator_only_and_points_move_with_the_input() -> None:
    v, f = _bumpy_sphere()
    a = _target_samples(v, f, 500, torch.Generator().manual_seed(0))
    moved = v * torch.tensor([1.3, 1.0, 0.7], dtype=torch.float64)  # every area changes
    b = _target_samples(moved, f, 500, torch.Generator().manual_seed(0))
    assert torch.equal(a.face_idx, b.face_idx)
    # The same barycentric points: the points move as the vertices do.
    torch.testing.assert_close(b.points, a.points * torch.tensor([1.3, 1.0, 0.7], dtype=torch.float64))
    rounded = _target_samples(v.float().double(), f, 500, torch.Generator().manual_seed(0))
    assert torch.equal(rounded.face_idx, a.face_idx)
    assert float((rounded.points - a.points).abs().max()) <= 2 * 2**-24 * float(v.abs().max())
    # float32 rounding moves the areas by ~1e-7 of themselves, and so the weights
    assert float(((rounded.weights - a.weights) / a.weights).abs().max()) <= 1e-6


def test_weighted_sums_estimate_the_area_integral() -> None:
    # sum_k w_k g(s_k) / sum_k w_k estimates the area-weighted mean of g, as the unweighted mean over area-proportional
    # draws does. For a linear g the exact value is sum_f A_f g(centroid_f) / sum_f A_f.
    v, f = _bumpy_sphere()
    direction = torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64)
    tri = v[f]
    area = 0.5 * torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1).norm(dim=-1)
    exact = float((area * (tri.mean(1) @ direction)).sum() / area.sum())
    s = _target_samples(v, f, 100 * f.shape[0], torch.Generator().manual_seed(0))
    assert float(s.weights.mean()) == pytest.approx(1.0, rel=1e-12)  # every face drawn 100 times: mean weight 1
    estimate = float((s.weights * (s.points @ direction)).sum() / s.weights.sum())
    # Measured |estimate - exact| over generator seeds 0-4: 1.6e-4 to 1.3e-3 (1.0e-3 at seed 0; g spans about +-6
    # here); the bound is ~4x the largest.
    assert abs(estimate - exact) <= 5e-3
    # Without the weights the mean is biased towards the small faces: off by 0.033 at every seed (0.0325-0.0339).
    assert abs(float((s.points @ direction).mean()) - exact) > 0.02


def test_more_samples_than_faces_cover_every_face_evenly() -> None:
    v, f = _bumpy_sphere()
    n = 3 * f.shape[0] + 17
    s = _target_samples(v, f, n, torch.Generator().manual_seed(0))
    counts = torch.bincount(s.face_idx, minlength=f.shape[0])
    assert int(counts.min()) == 3 and int(counts.max()) == 4 and int((counts == 4).sum()) == 17
    assert _target_samples(v, f, 0, torch.Generator().manual_seed(0)).points.shape == (0, 3)


def test_degenerate_faces_get_weight_zero_and_no_nan() -> None:
    v, f = _bumpy_sphere()
    f = torch.cat([f, f[:5, [0, 0, 1]], f[:5, [0, 1, 0]]])  # 10 zero-area faces (a repeated corner)
    s = _target_samples(v, f, 4 * f.shape[0], torch.Generator().manual_seed(0))
    on_degenerate = s.face_idx >= f.shape[0] - 10
    assert int(on_degenerate.sum()) == 40
    assert bool((s.weights[on_degenerate] == 0).all()) and bool((s.weights[~on_degenerate] > 0).all())
    assert bool(torch.isfinite(s.points).all() and torch.isfinite(s.weights).all())


def test_registration_with_mostly_degenerate_target_faces_is_finite() -> None:
    # A captured-like target with many zero-area faces, and more target samples than faces: the samples on zero-area
    # faces count with weight 0 in the reverse term and in the uncovered fraction.
    m = trimesh.creation.icosphere(subdivisions=2)
    tgt = add_capture_defects((m.vertices * [1.1, 1.0, 0.9], m.faces), seed=0, normalize=False)
    faces = torch.cat([tgt.faces, tgt.faces[:, [0, 0, 1]].repeat(3, 1)])  # three zero-area faces per face
    quick = {"num_target_samples": 4000, "rigid_init": False}
    with warnings.catch_warnings():
        # measured: the loss changed by 4.2e-4 of itself in the last window (tolerance 4e-4): not the point here
        warnings.simplefilter("ignore", RegistrationWarning)
        r = register_nonrigid(m, (tgt.verts, faces), generator=torch.Generator().manual_seed(0), **quick)
    assert not r.reason.startswith(("diverged", "implausible")), r.reason
    assert all(math.isfinite(x) for x in r.loss_history)
    assert bool(torch.isfinite(r.verts).all())
    diag = float((tgt.verts.amax(0) - tgt.verts.amin(0)).norm())
    assert float(r.residual.max()) <= 0.01 * diag  # measured 1.4e-3 of the diagonal


def test_weights_are_the_same_for_any_thread_count() -> None:
    # The weights scale the reverse term, so they must not depend on the thread count (docs/registration.md,
    # "Threads": 1 and 2 threads register alike bit for bit). Torch's sum of the 40k face areas of this frame splits
    # by thread (over 32k elements) and differed by 5.6e-17 between 1 and 2 threads, the weights by 4.4e-16 and every
    # registered vertex by up to 1.4e-14 (2026-12-05, 2-core x86-64); the mean area is now an exactly rounded sum.
    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.registration._common import normalisation
    from torchmeshmetric.structures import Mesh

    frame = demo_sequence(2, resolution=160).frames[1]
    mesh = Mesh(frame.verts.double(), frame.faces)
    center, diag = normalisation(mesh)
    verts = (mesh.verts - center) / diag  # the registration's frame, as _Fit passes it
    before = torch.get_num_threads()
    try:
        drawn = []
        for threads in (1, 2):
            torch.set_num_threads(threads)
            drawn.append(_target_samples(verts, mesh.faces, 2000, torch.Generator().manual_seed(0)))
    finally:
        torch.set_num_threads(before)
    assert mesh.num_faces > 32768
    assert torch.equal(drawn[0].weights, drawn[1].weights)
    assert torch.equal(drawn[0].points, drawn[1].points)
