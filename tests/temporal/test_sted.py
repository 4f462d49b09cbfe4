from __future__ import annotations

import math

import pytest
import torch

from tests.temporal.conftest import animated_sphere
from tests.temporal.naive import naive_sted
from torchmeshmetric._checks import IndexRangeError, ShapeError
from torchmeshmetric.temporal import sted
from torchmeshmetric.temporal.sted import largest_vertex_distance


def _distort(a: torch.Tensor, seed: int = 3, size: float = 0.02) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return a + size * torch.randn(a.shape, generator=g, dtype=a.dtype)


def test_equals_the_naive_reference(sphere_animation: tuple[torch.Tensor, torch.Tensor]) -> None:
    a, faces = sphere_animation
    b = _distort(a)
    for dt, window, c in ((3e-4, 5, 9.144e-5), (0.05, 1, 0.5)):
        r = sted(a, b, faces, dt=dt, window=window, c=c)
        ref = naive_sted(a.numpy(), b.numpy(), faces.numpy(), dt, window, c)
        # float64 sums in another order: agreement to a few ulps of values of order 1 (measured: < 4e-16).
        for got, want in zip(r, ref, strict=True):
            assert abs(got.item() - want) < 1e-13 * max(1.0, abs(want))


def test_invariants(sphere_animation: tuple[torch.Tensor, torch.Tensor]) -> None:
    a, faces = sphere_animation
    b = _distort(a)
    zero = sted(a, a, faces)
    assert zero.spatial.item() == 0.0 and zero.temporal.item() == 0.0 and zero.sted.item() == 0.0
    q, _ = torch.linalg.qr(torch.randn(3, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(1)))
    t = torch.tensor([0.3, -2.0, 5.0], dtype=torch.float64)
    moved = sted(a @ q.T + t, b @ q.T + t, faces)
    for got, want in zip(moved, sted(a, b, faces), strict=True):
        assert abs(got.item() - want.item()) < 1e-12
    assert sted(a, 1.7 * a, faces).spatial.item() < 1e-12  # a uniform scale has no spatial cost
    assert sted(a, 1.7 * a, faces).temporal.item() > 0.1  # ... but moves every vertex faster


def test_flicker_raises_temporal_not_spatial(sphere_animation: tuple[torch.Tensor, torch.Tensor]) -> None:
    a, faces = sphere_animation
    shift = torch.tensor([0.01, 0.0, 0.0], dtype=torch.float64)
    flicker = a + shift * (torch.arange(a.shape[0]) % 2)[:, None, None]  # whole frames jump back and forth
    r = sted(a, flicker, faces)
    steady = sted(a, a + shift, faces)  # the same offset in every frame: no jitter
    assert r.spatial.item() < 1e-12 and steady.spatial.item() < 1e-12
    assert steady.temporal.item() < 1e-12 and r.temporal.item() > 0.1


def test_batch_and_gradients(sphere_animation: tuple[torch.Tensor, torch.Tensor]) -> None:
    a, faces = sphere_animation
    b = _distort(a)
    batch = sted(torch.stack([a, a]), torch.stack([b, a]), faces)
    single = sted(a, b, faces)
    assert batch.sted.shape == (2,)
    assert batch.sted[0].item() == single.sted.item() and batch.sted[1].item() == 0.0
    small_a, small_faces = animated_sphere(num_frames=3, subdivisions=0)
    small_b = _distort(small_a).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda x: sted(small_a, x, small_faces, c=0.5).sted, (small_b,))
    same = small_a.clone().requires_grad_(True)
    sted(small_a, same, small_faces).sted.backward()  # at zero error: finite (zero) gradients
    assert same.grad is not None and bool(torch.isfinite(same.grad).all())


def test_largest_vertex_distance_is_exact() -> None:
    g = torch.Generator().manual_seed(0)
    x = torch.randn(3000, 3, dtype=torch.float64, generator=g) * 1e3 + 1e6
    want = torch.cdist(x - x.mean(0), x - x.mean(0), compute_mode="donot_use_mm_for_euclid_dist").max()
    assert largest_vertex_distance(x).item() == want.item()


def test_bad_input_is_named(sphere_animation: tuple[torch.Tensor, torch.Tensor]) -> None:
    a, faces = sphere_animation
    with pytest.raises(ShapeError, match="at least 2 frame"):
        sted(a[:1], a[:1], faces)
    with pytest.raises(IndexRangeError, match="faces"):
        sted(a, a, faces + 1000)
    with pytest.raises(ValueError, match="dt"):
        sted(a, a, faces, dt=0.0)
    with pytest.raises(ValueError, match="window"):
        sted(a, a, faces, window=-1)


@pytest.mark.parametrize("dt", [math.inf, math.nan, 1e200, 1e-200, -1.0])
def test_a_step_whose_square_is_no_finite_positive_float_is_refused(sphere_animation, dt) -> None:
    # STED squares dt: 1e200 overflowed and inf gave a NaN STED_t, which the final root then reported as STED 0.
    a, faces = sphere_animation
    with pytest.raises(ValueError, match=r"dt: expected a float > 0 whose square is a finite float > 0"):
        sted(a, a * 1.1, faces, dt=dt)


@pytest.mark.parametrize("bad", [None, "a", True])
def test_weights_that_are_not_numbers_are_named(sphere_animation, bad) -> None:
    a, faces = sphere_animation
    for name in ("dt", "c"):
        with pytest.raises(TypeError, match=f"{name}: expected a float, found"):
            sted(a, a, faces, **{name: bad})


def test_faces_without_an_edge_and_empty_batches(sphere_animation) -> None:
    a, faces = sphere_animation
    # a face of one repeated vertex has no edge: STED_s and STED_t were NaN and STED read 0
    with pytest.raises(ValueError, match="faces: no face has two distinct vertices"):
        sted(a, a * 1.1, torch.zeros(1, 3, dtype=torch.int64))
    nothing = a.new_zeros(0, *a.shape)  # a batch of no sequence, (0, F, V, 3): empty figures, as kg_error gives
    assert all(x.shape == (0,) for x in sted(nothing, nothing, faces))
    with pytest.raises(ShapeError, match=r"points: expected \(\.\.\., V, 3\) with V >= 1, found \(0, 3\)"):
        largest_vertex_distance(torch.zeros(0, 3))


def test_the_root_keeps_a_nan() -> None:
    from torchmeshmetric.temporal.sted import _safe_sqrt

    x = torch.tensor([4.0, 0.0, math.nan], dtype=torch.float64, requires_grad=True)
    y = _safe_sqrt(x)
    assert y[0].item() == 2.0 and y[1].item() == 0.0 and math.isnan(y[2].item())
    y[:2].sum().backward()
    assert x.grad is not None and x.grad[:2].tolist() == [0.25, 0.0]


@pytest.mark.parametrize("exponent", [-100, -70, 70, 100])
def test_float32_at_any_scale(sphere_animation: tuple[torch.Tensor, torch.Tensor], exponent: int) -> None:
    # Squares of float32 coordinates above ~1.8e19 overflowed (KG and STED NaN) and below ~1e-19 underflowed (KG
    # refused the original as "a single point"). Scaled by a power of two the inputs hold the same float32 values,
    # so the figures are the same bits (power_of_two_scale divides exactly).
    from torchmeshmetric.temporal import kg_error, kso_error

    a64, faces = sphere_animation
    a, b = a64.float(), _distort(a64).float()
    s = 2.0**exponent
    assert torch.equal(sted(a * s, b * s, faces).sted, sted(a, b, faces).sted)
    assert torch.equal(kg_error(a * s, b * s), kg_error(a, b))
    assert torch.equal(kso_error(a * s, b * s), kso_error(a, b) * s)
    assert torch.equal(kso_error(a * s, b * s, scale=True), kso_error(a, b, scale=True))
