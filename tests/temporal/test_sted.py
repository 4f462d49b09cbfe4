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


def _brute_force_diameter(x: torch.Tensor) -> float:
    """The largest distance of ``(V, 3)`` points over all V² pairs, computed as largest_vertex_distance computes it.

    The pair: the first (row-major) largest float64 ``((x_i - x_j) ** 2).sum()``; the distance: that pair's norm in
    the points' dtype. largest_vertex_distance must give these bits.
    """
    y = x.double()
    d2 = ((y[:, None, :] - y[None, :, :]) ** 2).sum(-1)
    flat = int(d2.argmax())
    i, j = flat // y.shape[0], flat % y.shape[0]
    return torch.linalg.vector_norm(x[i] - x[j]).item()


def _symmetric_cases() -> list[torch.Tensor]:
    """Point sets whose centroid lies on the farthest pair's segment, where the pruning bound is an equality."""
    import trimesh

    box = torch.as_tensor(trimesh.creation.box().vertices, dtype=torch.float64)  # cube [-0.5, 0.5]^3
    cases = [
        box * 0.37 + torch.tensor([0.5, -2.0, 3.0], dtype=torch.float64),  # review: D 0.5233 for 0.6409
        torch.cat([box + 0.5, torch.tensor([[5.0, 5.0, 5.0]], dtype=torch.float64)]),  # review: D = 0, STED_t NaN
        torch.tensor([[-1.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [10, 0, 0]]).double(),
    ]
    for sub in (0, 1, 2):  # review: an icosphere plus one point on an axis or diagonal gave D = 0 in 19 of 90
        sphere = torch.as_tensor(trimesh.creation.icosphere(subdivisions=sub).vertices, dtype=torch.float64)
        for distance in (2.0, 3.0, 5.0, 10.0, 100.0, 1e3):
            for direction in ((1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 1, 1)):
                u = torch.tensor(direction, dtype=torch.float64)
                cases.append(torch.cat([sphere, (distance * u / u.norm())[None]]))
    return cases


def test_largest_vertex_distance_is_the_brute_force_maximum_on_symmetric_sets() -> None:
    # The pruning kept r >= L - max(r) with no margin: on these sets the bound is tight and rounding dropped the true
    # partner. Every case must give the brute force's bits, in float64 and float32.
    wrong = []
    for k, x in enumerate(_symmetric_cases()):
        for dtype in (torch.float64, torch.float32):
            y = x.to(dtype)
            got, want = largest_vertex_distance(y).item(), _brute_force_diameter(y)
            if got != want:
                wrong.append((k, dtype, got, want))
    assert not wrong


@pytest.mark.parametrize("seed", range(6))
def test_largest_vertex_distance_is_the_brute_force_maximum_on_random_sets(seed: int) -> None:
    g = torch.Generator().manual_seed(seed)
    n = int(torch.randint(2, 400, (1,), generator=g))
    x = torch.randn(n, 3, dtype=torch.float64, generator=g) * 10.0 ** float(torch.randint(-3, 4, (1,), generator=g))
    x = x + torch.randn(3, dtype=torch.float64, generator=g) * 1e4  # far from the origin: rounding of x - c
    cube = torch.tensor([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=torch.float64)
    for y in (x, x.round(), torch.cat([x, x.mean(0) + (cube - 0.5) * x.std()])):  # ties, and a box around the centre
        assert largest_vertex_distance(y).item() == _brute_force_diameter(y)


def test_two_distinct_points_never_give_zero_and_coincident_points_give_zero() -> None:
    x = torch.tensor([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [1.0, 2.0, 3.0 + 2**-30]], dtype=torch.float64)
    assert largest_vertex_distance(x).item() == 2**-30
    assert largest_vertex_distance(torch.full((5, 3), 7.0)).item() == 0.0


def test_sted_of_a_cube_equals_the_naive_reference() -> None:
    # Review: D 18 % short on this cube, STED_t 0.05972 for the reference's 0.04925 (+21 %).
    import trimesh

    box = trimesh.creation.box()
    v0 = torch.as_tensor(box.vertices) * 0.37 + torch.tensor([0.5, -2.0, 3.0], dtype=torch.float64)
    a = torch.stack([v0 + 1e-4 * k for k in range(3)])
    b = a.clone()
    b[1, 0] += 1e-4
    got = sted(a, b, torch.as_tensor(box.faces))
    want = naive_sted(a.numpy(), b.numpy(), box.faces, 3e-4, 5, 9.144e-5)
    # float64 sums in another order: the bound of the reference test above (measured here: <= 1.1e-20 absolute)
    for g, w in zip(got, want, strict=True):
        assert abs(g.item() - w) < 1e-13 * max(1.0, abs(w))


def test_sted_refuses_a_frame_0_whose_referenced_vertices_coincide(sphere_animation) -> None:
    # D = 0 divides every temporal edge by zero (STED_t NaN): a clear error, naming what was found.
    a, faces = sphere_animation
    flat = a.clone()
    flat[0] = torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64)
    flat[0, -1] = 50.0  # a vertex far away, unreferenced: it is no part of the surface, so no scale either
    used = faces[faces.ne(a.shape[1] - 1).all(1)]
    with pytest.raises(ValueError, match=r"original: the vertices of frame 0 that faces reference all coincide"):
        sted(flat, flat * 1.1, used)


def test_an_unreferenced_vertex_takes_no_part(sphere_animation) -> None:
    # Review: a static vertex no face uses moved STED_t through D (0.0224592 against 0.0224443 without it).
    a, faces = sphere_animation
    b = _distort(a)
    stray = torch.tensor([3.0, 2.0, 1.0], dtype=torch.float64).expand(a.shape[0], 1, 3)
    with_stray = sted(torch.cat([a, stray], 1), torch.cat([b, stray + 0.5], 1), faces)
    for got, want in zip(with_stray, sted(a, b, faces), strict=True):
        assert got.item() == want.item()  # the same computations on the same vertices: the same bits
    a2, b2 = torch.cat([a, stray], 1).numpy(), torch.cat([b, stray], 1).numpy()
    ref = naive_sted(a2, b2, faces.numpy(), 3e-4, 5, 9.144e-5)
    assert abs(with_stray.temporal.item() - ref[1]) < 1e-13  # as the reference test above (measured: 0)


@pytest.mark.parametrize("bad", ["int", "nan", "complex", "list"])
def test_largest_vertex_distance_names_bad_points(bad: str) -> None:
    from torchmeshmetric._checks import DTypeError, NonFiniteError

    x = {
        "int": torch.tensor([[0, 0, 0], [3, 4, 0]]),
        "nan": torch.tensor([[0.0, 0, 0], [math.nan, 4, 0]]),
        "complex": torch.zeros(2, 3, dtype=torch.complex64),
        "list": [[0.0, 0, 0], [3.0, 4, 0]],
    }[bad]
    error, text = {
        "int": (DTypeError, r"points: expected a floating-point tensor .* found dtype torch.int64"),
        "nan": (NonFiniteError, r"points: expected finite values, found 1 NaN/Inf"),
        "complex": (DTypeError, r"points: expected a real floating-point tensor .* found dtype torch.complex64"),
        "list": (TypeError, r"points: expected a torch.Tensor of shape \(\.\.\., V, 3\), found list"),
    }[bad]
    with pytest.raises(error, match=text):
        largest_vertex_distance(x)  # type: ignore[arg-type]


def test_numpy_numbers_are_numbers(sphere_animation) -> None:
    # window=np.int64(3) was refused with a ValueError and dt=np.float32(3e-4) with "expected a float".
    np = pytest.importorskip("numpy")
    a, faces = sphere_animation
    b = _distort(a)
    want = sted(a, b, faces, dt=float(np.float32(3e-4)), window=3, c=0.5)
    got = sted(a, b, faces, dt=np.float32(3e-4), window=np.int64(3), c=np.float64(0.5))
    assert all(g.item() == w.item() for g, w in zip(got, want, strict=True))
    with pytest.raises(TypeError, match=r"window: expected an int, found float 1.5"):
        sted(a, b, faces, window=1.5)
    with pytest.raises(TypeError, match=r"dt: expected a float, found bool np.True_"):
        sted(a, b, faces, dt=np.bool_(True))
