"""Statistics, bounding-box diagonals and metrics of float64 meshes of extreme magnitude: the unit-size figures.

Review Q: below ~1e-154 ``rmse`` and ``std`` underflowed to 0 (``rmse = 0 < ave``, PSNR ``inf``), at 1e-160 they
were off by up to 6e-3; ``Mesh.bbox_diagonal`` squared unscaled coordinates, so at 1e-200 / 1e200 every distance
metric's ``compute()`` and ``evaluate_pair`` raised about a ``peak`` the user never gave.
"""

import math

import pytest
import torch
import trimesh

from torchmeshmetric import Mesh
from torchmeshmetric.evaluation import evaluate_pair
from torchmeshmetric.metrics import DistanceStatisticsMetric, MeshSurfaceDistance, NearestVertexDistance
from torchmeshmetric.stats import SketchRangeWarning, distance_statistics
from torchmeshmetric.structures import bbox_diagonal

SCALES = [1e-160, 1e-170, 1e-200, 1e-300, 1e150, 1e200, 1e300]


@pytest.mark.parametrize("s", [2.0**-560, 2.0**-700, 2.0**-1000, 2.0**500, 2.0**1000])
def test_statistics_at_powers_of_two_equal_the_unit_ones_bit_for_bit(s):
    d = torch.tensor([1.0, 2.0, 3.0, 0.25, 7.5], dtype=torch.float64)
    unit = distance_statistics(d, peak=10.0, ddof=1)
    got = distance_statistics(d * s, peak=10.0 * s, ddof=1)
    for name in ("ave", "rmse", "std", "max", "median"):
        assert float(getattr(got, name)) / s == float(getattr(unit, name)), name
    assert float(got.psnr) == pytest.approx(float(unit.psnr), rel=1e-14)


@pytest.mark.parametrize("s", SCALES)
def test_rmse_std_and_psnr_do_not_underflow_or_overflow(s):
    d = torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64)
    exact_rmse, exact_std = math.sqrt(14 / 3), math.sqrt(2 / 3)
    got = distance_statistics(d * s, peak=s)
    assert float(got.rmse) / s == pytest.approx(exact_rmse, rel=1e-15)
    assert float(got.std) / s == pytest.approx(exact_std, rel=1e-15)
    assert float(got.psnr) == pytest.approx(-10 * math.log10(14 / 3), rel=1e-12)
    # mse and var: their true values rounded (0 or inf only where those are past float64)
    assert float(got.mse) == pytest.approx(14 / 3 * s * s, rel=1e-12, abs=5e-324)
    assert float(got.var) == pytest.approx(2 / 3 * s * s, rel=1e-12, abs=5e-324)


def test_a_batch_and_a_metric_stream_scale_each_item_by_its_own():
    d = torch.tensor([1e-170, 2e-170, 3e-170, 1.0, 2.0], dtype=torch.float64)
    b = distance_statistics(d, lengths=torch.tensor([3, 2]))
    assert float(b.rmse[0]) == pytest.approx(math.sqrt(14 / 3) * 1e-170, rel=1e-15)
    assert float(b.rmse[1]) == math.sqrt(2.5) and float(b.var[1]) == 0.25
    m = DistanceStatisticsMetric(peak=1e-170)
    for v in (1e-170, 2e-170, 3e-170):
        m.update(torch.tensor([v], dtype=torch.float64))
    out = m.compute()
    assert float(out["rmse"]) == pytest.approx(math.sqrt(14 / 3) * 1e-170, rel=1e-15)
    assert float(out["std"]) == pytest.approx(math.sqrt(2 / 3) * 1e-170, rel=1e-15)


def test_the_sketch_says_it_does_not_know_an_underflowed_root():
    # the sketch keeps no values: a root its moments lost is NaN, never a 0 below ave
    m = DistanceStatisticsMetric(exact_quantiles=False)
    m.update(torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64) * 1e-170)
    with pytest.warns(SketchRangeWarning, match="below min_value"):  # its quantiles too (fixed window; review V)
        got = m.compute()
    assert math.isnan(float(got["rmse"])) and math.isnan(float(got["std"]))
    assert float(got["ave"]) == pytest.approx(2e-170, rel=1e-15)
    m = DistanceStatisticsMetric(exact_quantiles=False)
    m.update(torch.full((4,), 1e-300, dtype=torch.float64))
    with pytest.warns(SketchRangeWarning, match="below min_value"):
        got = m.compute()
    assert float(got["var"]) == 0.0 and float(got["std"]) == 0.0


@pytest.mark.parametrize("s", [1.0, 3.7, 1e-160, 1e-200, 1e-300, 1e200, 1e300])
def test_bbox_diagonal_scales_exactly(s):
    m = trimesh.creation.icosphere(subdivisions=1)
    unit = Mesh(torch.tensor(m.vertices), torch.tensor(m.faces)).bbox_diagonal()
    got = Mesh(torch.tensor(m.vertices) * s, torch.tensor(m.faces)).bbox_diagonal()
    assert float(got) / s == pytest.approx(float(unit), rel=1e-15)
    assert float(bbox_diagonal(torch.tensor(m.vertices, dtype=torch.float32) * 1e-30)) > 0


def test_bbox_diagonal_has_the_plain_norms_bits_where_nothing_overflows():
    g = torch.Generator().manual_seed(0)
    for dtype in (torch.float32, torch.float64):
        for _ in range(50):
            v = torch.randn(30, 3, generator=g, dtype=torch.float64).to(dtype) * float(torch.rand(1, generator=g)) * 1e3
            plain = (v.amax(0) - v.amin(0)).to(torch.float64).norm().to(dtype)
            assert torch.equal(bbox_diagonal(v), plain)


def sphere_pair(s: float):
    a, b = trimesh.creation.icosphere(subdivisions=1), trimesh.creation.icosphere(subdivisions=3)
    simplified = (torch.tensor(a.vertices) * 1.1 * s, torch.tensor(a.faces))
    return simplified, (torch.tensor(b.vertices) * s, torch.tensor(b.faces))


@pytest.mark.parametrize("metric", [MeshSurfaceDistance, NearestVertexDistance])
@pytest.mark.parametrize("s", [1e-160, 1e-200, 1e-300, 1e200, 1e300])
def test_distance_metrics_at_extreme_magnitudes_give_the_unit_figures(metric, s):
    unit, far = metric(), metric()
    unit.update(*sphere_pair(1.0))
    far.update(*sphere_pair(s))
    u, f = unit.compute(), far.compute()
    for name in ("ave", "rmse", "max", "std"):
        assert float(f[name]) / s == pytest.approx(float(u[name]), rel=1e-13, abs=1e-15), name
    assert float(f["psnr"]) == pytest.approx(float(u["psnr"]), rel=1e-13)


def test_a_derived_peak_of_zero_names_the_reference_not_peak():
    point = (torch.zeros(3, 3, dtype=torch.float64), torch.tensor([[0, 1, 2]]))
    m = MeshSurfaceDistance()
    m.update(sphere_pair(1.0)[0], point)
    with pytest.raises(ValueError, match=r"^reference \(the largest diagonal measured\): its bounding-box diagonal"):
        m.compute()


@pytest.mark.parametrize("s", [1e-200, 1e200])
def test_evaluate_pair_at_extreme_magnitudes(s):
    def identity(source, target):
        return source

    unit_a, unit_b = sphere_pair(1.0)
    a, b = sphere_pair(s)
    u = evaluate_pair(unit_a, unit_b, unit_b, registration_fn=identity)
    f = evaluate_pair(a, b, b, registration_fn=identity)
    for name, st in u.statistics.items():
        assert float(f.statistics[name].rmse) / s == pytest.approx(float(st.rmse), rel=1e-13), name
        assert float(f.statistics[name].psnr) == pytest.approx(float(st.psnr), rel=1e-13), name
    assert f.peak / s == pytest.approx(u.peak, rel=1e-15)
