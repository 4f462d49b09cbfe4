"""sample_surface (area-weighted, reproducible, on the surface) and vertex_set."""

from __future__ import annotations

import pytest
import torch
import trimesh

from torchmeshmetric import EmptyInputError, Mesh, point_mesh_distance, sample_surface, vertex_set


def _two_triangles() -> Mesh:
    # Areas 0.5 and 1.5: a uniform sampler puts 25 % of the samples on face 0.
    v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [8, 0, 0], [5, 1, 0]], dtype=torch.float64)
    return Mesh(v, torch.tensor([[0, 1, 2], [3, 4, 5]]))


def test_area_weighting() -> None:
    n = 40_000
    s = sample_surface(_two_triangles(), n=n, generator=torch.Generator().manual_seed(0))
    frac = float((s.face_idx == 0).double().mean())
    sigma = (0.25 * 0.75 / n) ** 0.5
    assert abs(frac - 0.25) < 5 * sigma


def test_uniform_within_a_triangle() -> None:
    # For the unit right triangle, a uniform sample has E[x] = E[y] = 1/3 and P(x + y < 1/2) = 1/4.
    v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=torch.float64)
    n = 40_000
    s = sample_surface(v, torch.tensor([[0, 1, 2]]), n, generator=torch.Generator().manual_seed(1))
    mean = s.points.mean(0)
    sd = (1 / 18) ** 0.5 / n**0.5
    assert abs(float(mean[0]) - 1 / 3) < 5 * sd and abs(float(mean[1]) - 1 / 3) < 5 * sd
    frac = float((s.points[:, :2].sum(1) < 0.5).double().mean())
    assert abs(frac - 0.25) < 5 * (0.25 * 0.75 / n) ** 0.5


def test_reproducible_and_on_surface() -> None:
    m = trimesh.creation.icosphere(subdivisions=2)
    a = sample_surface(m, n=500, generator=torch.Generator().manual_seed(7))
    b = sample_surface(m, n=500, generator=torch.Generator().manual_seed(7))
    c = sample_surface(m, n=500, generator=torch.Generator().manual_seed(8))
    assert torch.equal(a.points, b.points) and not torch.equal(a.points, c.points)
    assert float(point_mesh_distance(a.points, m).dists.max()) < 1e-12
    torch.testing.assert_close(a.bary.sum(1), torch.ones(500, dtype=a.bary.dtype))
    assert bool((a.bary >= 0).all())


def test_ragged_batch_and_gradient() -> None:
    m1, m2 = _two_triangles(), Mesh(_two_triangles().verts * 2, _two_triangles().faces)
    verts = m1.verts.clone().requires_grad_()
    s = sample_surface([Mesh(verts, m1.faces), m2], n=[10, 30], generator=torch.Generator().manual_seed(0))
    assert s.lengths.tolist() == [10, 30] and s.points.shape == (40, 3)
    assert bool((s.face_idx[:10] < 2).all()) and bool((s.face_idx[10:] >= 2).all())
    s.points.sum().backward()
    assert verts.grad is not None and float(verts.grad.abs().sum()) > 0


def test_later_item_after_a_much_larger_one() -> None:
    # Review D §12: one cumsum over the batch made the small box's CDF a difference of sums of the big box's areas
    # (area ratio ~1e15), and all 120 000 of its samples fell on its last face. Each of its 12 equal faces gets ~10 000.
    box = trimesh.creation.box()
    v, f = torch.tensor(box.vertices, dtype=torch.float64), torch.tensor(box.faces)
    n = 120_000
    s = sample_surface([(v * 3e7, f), (v, f)], n=[10, n], generator=torch.Generator().manual_seed(0))
    assert bool((s.face_idx[:10] < 12).all())
    counts = torch.bincount(s.face_idx[10:] - 12, minlength=12)
    sigma = (n * (1 / 12) * (11 / 12)) ** 0.5
    assert counts.shape == (12,) and bool(((counts - n / 12).abs() < 5 * sigma).all()), counts.tolist()
    # On it, too: the samples are points of the small box.
    assert float(point_mesh_distance(s.points[10:], v, f).dists.max()) < 1e-12


def test_item_scaling_keeps_the_samples() -> None:
    # The per-item scaling is by a power of two (exact): a single mesh samples as it did before the fix (values
    # recorded from the unscaled code), and its samples in a batch's first place are its samples alone.
    m = trimesh.creation.icosphere(subdivisions=2)
    a = sample_surface(m, n=6, generator=torch.Generator().manual_seed(3))
    assert a.face_idx.tolist() == [11, 92, 247, 56, 241, 194]
    b = sample_surface([m, _two_triangles()], n=[6, 4], generator=torch.Generator().manual_seed(3))
    assert torch.equal(b.face_idx[:6], a.face_idx)


def test_zero_area_and_bad_n() -> None:
    v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    with pytest.raises(EmptyInputError, match="mesh 0 has zero surface area"):
        sample_surface(v, torch.tensor([[0, 1, 2]]), 5)
    with pytest.raises(ValueError, match="n: expected an int >= 0, found -1"):
        sample_surface(_two_triangles(), n=-1)


def test_vertex_set_drops_unreferenced_only() -> None:
    v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [9, 9, 9], [1, 0, 0]])
    f = torch.tensor([[0, 1, 2], [4, 1, 2]])
    assert vertex_set((v, f)).tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0]]
    assert vertex_set((v, f), referenced_only=False).shape == (5, 3)


# Areas 0.5 and 50: 1 % of the samples on face 0 (review V, F3).
_SMALL_AND_LARGE = (
    torch.tensor([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [10, 0, 1], [0, 10, 1]], dtype=torch.float64),
    torch.tensor([[0, 1, 2], [3, 4, 5]]),
)


@pytest.mark.parametrize(
    ("dtype", "exponent"),
    [
        *((torch.float32, k) for k in (33, 66, -83, -140)),
        *((torch.float64, k) for k in (260, 600, -565, -1060)),
    ],
)
def test_samples_of_a_mesh_scaled_by_a_power_of_two_are_the_same_samples(dtype, exponent):
    # Areas were formed in the input dtype, whose |cross|**2 overflowed float32 beyond edges of ~1e9 (at 1e20 every
    # sample fell on the overflowing face: 0 % on face 0 instead of 1 %) and underflowed below ~1e-9 (a valid mesh at
    # 1e-25: "zero surface area"); float64 likewise at ~1e-170. A power of two scales exactly, so the same seed must
    # give the same faces and barycentrics, and the points times that power, at any magnitude the dtype holds.
    verts, faces = _SMALL_AND_LARGE
    verts = verts.to(dtype)
    scale = 2.0**exponent
    unit = sample_surface(verts, faces, 2000, generator=torch.Generator().manual_seed(3))
    got = sample_surface(verts * scale, faces, 2000, generator=torch.Generator().manual_seed(3))
    assert torch.equal(got.face_idx, unit.face_idx)
    assert torch.equal(got.bary, unit.bary)
    if exponent > -120:  # subnormal points round (the faces and barycentrics above are exact)
        assert torch.equal(got.points, unit.points * scale)
    assert 0.005 < float((got.face_idx == 0).double().mean()) < 0.02


def test_a_mesh_at_an_extreme_magnitude_leaves_the_others_of_a_batch_alone():
    verts, faces = _SMALL_AND_LARGE
    ordinary = (verts.float() * 3.7, faces)
    g = torch.Generator()
    alone = sample_surface([ordinary, (verts.float(), faces)], n=[500, 500], generator=g.manual_seed(5))
    mixed = sample_surface([ordinary, (verts.float() * 2.0**70, faces)], n=[500, 500], generator=g.manual_seed(5))
    assert torch.equal(mixed.face_idx, alone.face_idx)
    assert torch.equal(mixed.points[:500], alone.points[:500])
    assert torch.equal(mixed.points[500:], alone.points[500:] * 2.0**70)
