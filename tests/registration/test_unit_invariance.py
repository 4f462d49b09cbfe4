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
