"""A pair in other units (every coordinate times ``s``) registers to ``s`` times the registration.

Found 2026-12-07: the point-to-plane rigid step damped its normal equations by one number relative to their largest
diagonal entry, while the rotation's entries scale with ``s**2`` and the translation's do not, so the rotation was
damped more or less with the units. A power-of-two scale (exact in floating point) changed the registration (up to
7.5e-14 of the diagonal, float64, on the pairs below), 1e-3 units by up to 5.2e-7 (float64) and 8.5e-2 (float32: the
rotation barely moved), and the evaluation's k-1 statistics by 3.1e-7 relative (demo, resolution 24). The step now
divides the rotation's columns by a length of the data (``_point_to_plane_step``).
"""

import pytest
import torch
import trimesh
from torch import Tensor

from torchmeshmetric import Mesh
from torchmeshmetric.data.demo import demo_sequence
from torchmeshmetric.evaluation import evaluate_pair
from torchmeshmetric.registration import register_rigid, skinning_weights
from torchmeshmetric.simplification import simplify_qem

Pair = tuple[tuple[Tensor, Tensor], tuple[Tensor, Tensor]]


def _rotated_pair() -> Pair:
    """A bumpy ellipsoid (no symmetry) and its copy rotated by 0.3 rad and translated: a well-posed rigid pair."""
    ico = trimesh.creation.icosphere(subdivisions=2)
    v = torch.tensor(ico.vertices, dtype=torch.float64)
    f = torch.tensor(ico.faces)
    bumps = 1 + 0.03 * torch.rand(v.shape[0], 1, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    v = v * torch.tensor([1.0, 0.8, 0.6], dtype=torch.float64) * bumps
    R = torch.tensor(trimesh.transformations.rotation_matrix(0.3, [1, 2, 3])[:3, :3])
    return (v, f), (v @ R.T + torch.tensor([0.05, -0.02, 0.03], dtype=torch.float64), f)


def _demo_pair() -> Pair:
    """Demo frames 0 -> 1 at resolution 24 (~440 vertices): the evaluation's kind of pair, non-rigidly moved."""
    f0, f1 = demo_sequence(2, resolution=24, dtype=torch.float64).frames
    return (f0.verts, f0.faces), (f1.verts, f1.faces)


PAIRS = {"rotated": _rotated_pair, "demo": _demo_pair}
MODES = [{"point_to_plane": True}, {"point_to_plane": True, "scale": True}]


def _register(pair: Pair, s: float, dtype: torch.dtype, mode: dict):
    (sv, sf), (tv, tf) = pair
    # Scaled in float64, then rounded to the dtype: the input a user in those units would have.
    return register_rigid(((sv * s).to(dtype), sf), ((tv * s).to(dtype), tf), sampling="canonical", **mode)


@pytest.mark.parametrize("mode", MODES, ids=["rigid", "similarity"])
@pytest.mark.parametrize("pair", list(PAIRS))
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_point_to_plane_registration_at_twice_the_size_is_twice_the_registration_bit_for_bit(dtype, pair, mode):
    # Doubling is exact, and so is every step of the registration under it (the step's length is sqrt of a sum of
    # squares, scaled by exactly 2): the same bits. Before: up to 7.5e-14 (float64) and 8.3e-8 (float32) of the
    # diagonal.
    p = PAIRS[pair]()
    a, b = _register(p, 1.0, dtype, mode), _register(p, 2.0, dtype, mode)
    assert a.converged and b.iterations == a.iterations
    assert torch.equal(b.verts, 2 * a.verts)
    assert torch.equal(b.rotation, a.rotation) and torch.equal(b.scale, a.scale)
    assert torch.equal(b.translation, 2 * a.translation) and torch.equal(b.rmse, 2 * a.rmse)


@pytest.mark.parametrize("s", [1e3, 1e-3])
@pytest.mark.parametrize("mode", MODES, ids=["rigid", "similarity"])
@pytest.mark.parametrize("pair", list(PAIRS))
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_point_to_plane_registration_in_other_units_differs_by_rounding(dtype, pair, mode, s):
    # Measured (2026-12-07, these pairs, canonical sampling): the registered vertices / s differ from the unit pair's
    # by <= 1.9e-16 of the diagonal in float64 and <= 1.1e-7 in float32, about as much as scaling the input by one
    # ulp (1 + 2**-50: <= 1.9e-16; float32, 1 + 2**-22: <= 7.8e-8), the input's own rounding (each coordinate times
    # s is rounded on its own). The bounds are ~10x the measurement. Before: float64 up to 5.2e-7 (1e-3 units) and
    # 1.8e-9 (1e3); float32 up to 8.5e-2 (1e-3) and 1.4e-4 (1e3).
    p = PAIRS[pair]()
    bound = {torch.float64: 2e-15, torch.float32: 1e-6}[dtype]
    a, b = _register(p, 1.0, dtype, mode), _register(p, s, dtype, mode)
    diag = float((p[1][0].amax(0) - p[1][0].amin(0)).norm())
    assert a.converged and b.converged
    assert float((b.verts.double() / s - a.verts.double()).abs().max()) <= bound * diag
    assert float((b.rotation - a.rotation).abs().max()) <= bound


_LENGTHS = ("ave", "std", "rmse", "max", "min", "median", "p95", "p99")


@pytest.mark.parametrize("s", [2.0, 1e3, 1e-3])
def test_evaluation_k_minus_1_statistics_do_not_depend_on_the_units(s):
    # The k-1 sets are distances of registered frame k-1: s times the unit pair's. Doubling is exact along the whole
    # path (validate_pair, the rigid step, the normalised frame): the same bits. Measured (2026-12-07, demo 0 -> 1 at
    # resolution 24, QEM at 10 %) at 1e3 and 1e-3 units: every statistic within 2.8e-14 relative, except the Min
    # (1e-5 of the diagonal; 2.0e-11 relative), and every length within 7.6e-16 of the diagonal absolute; one ulp of
    # input (1 +- 2**-50) moves them by 1.0e-14, the Min by 1.0e-13, 2.7e-16 of the diagonal. A distance is known to
    # the coordinates' rounding, absolutely, so a length may differ by 5e-15 of the diagonal or 1e-12 relative (~7x
    # and ~35x the measurement; the docs' one-ulp bound for these sets at full size is 1.7e-11 relative). Before:
    # 2.4e-10 relative / 6.4e-12 of the diagonal at 1e3 and 3.1e-7 / 8.4e-9 at 1e-3 (the damping), 1.0e-13 at 2.
    f0, f1 = demo_sequence(2, resolution=24, dtype=torch.float64).frames
    simp = simplify_qem(f1, 0.1)
    diag = float((f1.verts.amax(0) - f1.verts.amin(0)).norm())

    def scaled(m: Mesh, k: float) -> Mesh:
        return Mesh(m.verts * k, m.faces)

    a = evaluate_pair(simp, f1, f0).statistics
    b = evaluate_pair(scaled(simp, s), scaled(f1, s), scaled(f0, s)).statistics
    for key in ("surface_k_minus_1", "vertex_k_minus_1"):
        assert int(b[key].count) == int(a[key].count)
        for name, power in [(n, 1) for n in _LENGTHS] + [("var", 2), ("mse", 2), ("psnr", 0)]:
            x, y = float(getattr(a[key], name)), float(getattr(b[key], name)) / s**power
            if s == 2.0:
                assert y == x, (key, name)
            else:
                assert y == pytest.approx(x, rel=1e-12, abs=5e-15 * diag if power == 1 else 0.0), (key, name)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_skinning_weights_of_few_nodes_do_not_depend_on_the_units(dtype):
    # With no more nodes than K there is no (K+1)-th distance: the weights divide by 1.5x the farthest node's, to
    # which 1e-12 (absolute) was added: at 2**-40 units (~1e-12) the weights moved by 0.21, at 2**-20 by 6.6e-7
    # (found 2026-12-07). A power of two now gives the same bits; a point on every node still gets equal weights.
    g = torch.Generator().manual_seed(0)
    points = torch.rand(50, 3, generator=g, dtype=torch.float64).to(dtype)
    nodes = torch.rand(3, 3, generator=g, dtype=torch.float64).to(dtype)
    idx, w = skinning_weights(points, nodes, 4)
    for k in (-40, 40):
        idx_k, w_k = skinning_weights(points * 2.0**k, nodes * 2.0**k, 4)
        assert torch.equal(idx_k, idx) and torch.equal(w_k, w)
    _, w0 = skinning_weights(torch.zeros(1, 3, dtype=dtype), torch.zeros(2, 3, dtype=dtype), 4)
    assert torch.equal(w0, torch.full((1, 2), 0.5, dtype=dtype))


# Review S (2026-12-07): with L the samples' spread alone the step was not continuous. Samples that are all one point
# have a spread of the centroid's rounding (1e-19 at 1e-3 units), so the divided rotation columns were rounding noise
# of size 1 (rotation 1.7 rad, scale inf), and a sample of weight 1e-300 set a 0.14 rad rotation. L is now at least
# 1/16 of the target diagonal; the rotation goes to 0 with the spread.


def _angle(rotation: Tensor) -> float:
    return float(torch.linalg.matrix_norm(rotation - torch.eye(3, dtype=rotation.dtype)))


@pytest.mark.parametrize("scale", [False, True], ids=["rigid", "similarity"])
@pytest.mark.parametrize("weights", ["equal", "unequal"])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_point_to_plane_step_of_coincident_samples_turns_by_rounding_only(dtype, weights, scale):
    # 20 copies of one point at 1e-3 units, random normals, targets 1e-5 away: no rotation or scale is constrained.
    # Measured: |R - I| <= 2.5e-16 (float64) / 1.4e-7 (float32), |s - 1| <= 4.5e-16 / 1.2e-7. Before: 1.1-2.8 rad, and
    # s = inf with scale (float32 too where unequal weights leave the centroid rounded).
    from torchmeshmetric.registration.rigid import _point_to_plane_step

    g = torch.Generator().manual_seed(1)
    p = torch.tensor([[0.3, 0.7, 0.1]], dtype=dtype).repeat(20, 1) * 1e-3
    n = torch.nn.functional.normalize(torch.randn(20, 3, generator=g).to(dtype), dim=-1)
    q = p + 1e-5 * torch.randn(20, 3, generator=g).to(dtype)
    w = torch.ones(20, dtype=dtype)
    if weights == "unequal":
        w[::3] = 0.7
    diag = torch.tensor(1e-3, dtype=dtype)
    step = _point_to_plane_step(p, q, n, w, scale, diag)
    tol = 2e-6 if dtype == torch.float32 else 3e-15
    assert _angle(step.rotation) <= tol
    assert abs(float(step.scale) - 1) <= tol
    assert bool(torch.isfinite(step.translation).all()) and float(step.translation.abs().max()) <= 1e-4
    twice = _point_to_plane_step(2 * p, 2 * q, n, w, scale, 2 * diag)
    assert torch.equal(twice.rotation, step.rotation) and torch.equal(twice.translation, 2 * step.translation)


def test_point_to_plane_step_turns_less_and_less_as_a_weight_goes_to_0():
    # A heavy sample at the origin on its plane, two light ones at distance 1, one 0.1 off its plane: weight eps on
    # the light ones. The rotation they ask for is 0.14 rad; with weight 0 there is none. Measured: |R - I| = 1.8e10
    # eps for eps <= 1e-16, 0 at 1e-300, 0.14 from 1e-9 up, monotone. Before: 0.14 rad for every eps > 0 (1e-300 too).
    from torchmeshmetric.registration.rigid import _point_to_plane_step
    from torchmeshmetric.structures import bbox_diagonal

    p = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=torch.float64)
    n = torch.tensor([[0.0, 0, 1]] * 3, dtype=torch.float64)
    q = p.clone()
    q[1, 2] = 0.1
    diag = bbox_diagonal(q)
    angles = []
    for eps in [0.0, 1e-300, 1e-100, 1e-30, 1e-20, 1e-16, 1e-12, 1e-9, 1e-6, 1e-3]:
        step = _point_to_plane_step(p, q, n, torch.tensor([1.0, eps, eps], dtype=torch.float64), False, diag)
        angles.append(_angle(step.rotation))
        if eps <= 1e-16:
            assert angles[-1] <= 2e11 * eps
    assert angles[:2] == [0.0, 0.0]
    assert angles == sorted(angles)
    assert angles[-1] == pytest.approx(0.1414, rel=1e-3)


def _fan(dtype: torch.dtype) -> Pair:
    """An unwelded fan of 20 triangles at 1e-3 units (each stores its own apex) and its copy tilted 0.2 rad about the
    apex: with trim 1/3 the kept samples are exactly the apex copies, which constrain no rotation."""
    k = 20
    apex = torch.tensor([0.3e-3, 0.7e-3, 0.1e-3], dtype=torch.float64)
    ang = torch.arange(k + 1, dtype=torch.float64) * 2 * torch.pi / k
    ring = torch.stack([torch.cos(ang), torch.sin(ang), torch.zeros_like(ang)], 1) * 1e-3 + apex
    ring = ring - torch.tensor([0, 0, 0.5e-3], dtype=torch.float64)
    v = torch.stack([x for i in range(k) for x in (apex, ring[i], ring[i + 1])])
    f = torch.arange(3 * k).reshape(k, 3)
    m = torch.tensor(trimesh.transformations.rotation_matrix(0.2, [1, 0, 0], point=apex.tolist())[:3, :])
    return (v.to(dtype), f), ((v @ m[:, :3].T + m[:, 3]).to(dtype), f)


@pytest.mark.parametrize("scale", [False, True], ids=["rigid", "similarity"])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_registration_on_samples_that_constrain_no_rotation_does_not_turn(dtype, scale):
    # Measured: the identity (as before the unit-invariant step), s = 1. Before: 0.0625 rad (|R - I| = 0.088) in
    # float32 and float64, from the last bits of the centroid.
    (sv, sf), (tv, tf) = _fan(dtype)
    opts = {"point_to_plane": True, "scale": scale, "trim": 1 / 3, "align_centroids": False, "max_iterations": 30}
    r = register_rigid((sv, sf), (tv, tf), **opts)
    assert r.converged
    assert _angle(r.rotation) <= 1e-6
    assert abs(float(r.scale) - 1) <= 1e-6
    assert bool(torch.isfinite(r.verts).all())
    twice = register_rigid((2 * sv, sf), (2 * tv, tf), **opts)
    assert torch.equal(twice.rotation, r.rotation) and torch.equal(twice.verts, 2 * r.verts)
