"""``plot()`` of every metric class (torchmetrics' convention: ``fig, ax = metric.plot()``), rendered to files."""

from __future__ import annotations

import inspect

import pytest
import torch
import trimesh
from torchmetrics import Metric

pytest.importorskip("matplotlib")

import matplotlib.pyplot as plt

import torchmeshmetric.metrics as metrics
from torchmeshmetric.metrics import (
    DistanceStatisticsMetric,
    MeshSurfaceDistance,
    NearestVertexDistance,
    SelectedStatistic,
)
from torchmeshmetric.metrics._plot import bar_label, length_keys

PNG = b"\x89PNG\r\n\x1a\n"


def _metric_classes() -> list[type]:
    """Every public ``torchmetrics.Metric`` class of ``torchmeshmetric.metrics``."""
    found = [getattr(metrics, n) for n in metrics.__all__]
    return [c for c in found if inspect.isclass(c) and issubclass(c, Metric)]


def _updated(cls: type, two_sided: bool = False) -> Metric:
    sphere = trimesh.creation.icosphere(subdivisions=2)
    points = torch.tensor([[0.0, 0.0, 2.0], [0.0, 3.0, 0.0], [0.5, 0.0, 0.0]])
    if cls is DistanceStatisticsMetric:
        m = DistanceStatisticsMetric(two_sided=two_sided)
        m.update(torch.tensor([1.0, 2.0, 6.0]), torch.tensor([0.5, 0.25]) if two_sided else None)
        return m
    if cls is SelectedStatistic:
        source = _updated(MeshSurfaceDistance)
        return source.statistic("rmse")
    if cls.__name__ == "DistanceStatisticsBase":
        return _updated(DistanceStatisticsMetric, two_sided)
    m = cls(two_sided=two_sided)
    m.update(points if not two_sided else trimesh.creation.icosphere(subdivisions=1), sphere)
    return m


def _saved(fig, tmp_path, name: str) -> bytes:
    path = tmp_path / f"{name}.png"
    fig.savefig(path)
    plt.close(fig)
    return path.read_bytes()


def test_every_metric_class_is_covered():
    names = {c.__name__ for c in _metric_classes()}
    assert names == {
        "DistanceStatisticsBase",
        "DistanceStatisticsMetric",
        "MeshSurfaceDistance",
        "NearestVertexDistance",
        "SelectedStatistic",
    }


@pytest.mark.parametrize("cls", _metric_classes(), ids=lambda c: c.__name__)
def test_plot_draws_the_computed_values(cls, tmp_path):
    metric = _updated(cls)
    fig, ax = metric.plot()
    out = metric.compute()
    if isinstance(out, dict):  # one bar a statistic in the unit of the distances, the height the value
        keys = length_keys(list(out))
        assert [t.get_text() for t in ax.get_xticklabels()] == keys
        assert [p.get_height() for p in ax.patches] == pytest.approx([float(out[k]) for k in keys], rel=1e-12)
        assert "var" not in keys and "psnr" not in keys and "count" not in keys
    else:  # a scalar: torchmetrics' own drawing, one point
        (line,) = ax.get_lines()[:1]
        assert list(line.get_ydata()) == pytest.approx([float(out)], rel=1e-12)
    # a view is named by its statistic (every view was labelled "SelectedStatistic": review A, finding 7)
    expected = metric.key if cls is SelectedStatistic else cls.__name__
    assert ax.get_ylabel() == expected if cls.__name__ != "DistanceStatisticsBase" else True
    assert _saved(fig, tmp_path, cls.__name__)[:8] == PNG


@pytest.mark.parametrize("cls", [MeshSurfaceDistance, NearestVertexDistance, DistanceStatisticsMetric])
def test_two_sided_bars_name_both_directions(cls):
    metric = _updated(cls, two_sided=True)
    fig, ax = metric.plot()
    labels = [t.get_text() for t in ax.get_xticklabels()]
    assert "reverse_rmse" in labels and "symmetric_rmse" in labels and "hausdorff" in labels
    out = metric.compute()
    assert [p.get_height() for p in ax.patches] == pytest.approx([float(out[k]) for k in labels], rel=1e-12)
    # forward, reverse and symmetric bars in three colours
    colours = {tuple(p.get_facecolor()) for p in ax.patches}
    assert len(colours) == 3
    plt.close(fig)


def test_steps_are_curves_and_keys_select(tmp_path):
    metric = DistanceStatisticsMetric()
    steps = []
    for batch in ([1.0, 2.0], [3.0, 5.0], [0.5]):
        metric.update(torch.tensor(batch))
        steps.append(metric.compute())
    fig, ax = metric.plot(steps, keys=["ave", "max"])
    lines = {
        line.get_label(): list(line.get_ydata()) for line in ax.get_lines() if not line.get_label().startswith("_")
    }
    assert lines["ave"] == pytest.approx([1.5, 2.75, 2.3])
    assert lines["max"] == pytest.approx([2.0, 5.0, 5.0])
    assert ax.get_xlabel() == "Step"
    assert _saved(fig, tmp_path, "steps")[:8] == PNG


def test_given_axes_are_drawn_into():
    metric = _updated(MeshSurfaceDistance)
    fig, ax = plt.subplots()
    f, a = metric.plot(ax=ax, keys=["psnr"])
    assert f is None and a is ax
    assert ax.patches[0].get_height() == pytest.approx(float(metric.compute()["psnr"]), rel=1e-12)
    plt.close(fig)


def test_selected_statistic_marks_its_direction():
    source = _updated(MeshSurfaceDistance)
    fig, ax = source.statistic("psnr").plot([source.compute()["psnr"], source.compute()["psnr"] + 1])
    assert [float(v) for v in ax.get_lines()[0].get_ydata()] == pytest.approx(
        [float(source.compute()["psnr"]), float(source.compute()["psnr"]) + 1]
    )
    plt.close(fig)


def test_bad_requests_are_refused():
    metric = _updated(DistanceStatisticsMetric)
    with pytest.raises(KeyError, match="keys: \\['nope'\\] not in the result"):
        metric.plot(keys=["nope"])
    with pytest.raises(ValueError, match="empty list"):
        metric.plot([])
    with pytest.raises(
        TypeError, match=r"keys: expected a list of statistic names, found the string 'ave' \(write \['ave'\]\)"
    ):
        metric.plot(keys="ave")  # type: ignore[arg-type]  # was drawn as the keys "a", "v", "e"
    first = metric.compute()
    with pytest.raises(KeyError, match=r"val\[1\]: \['ave'\] not in this step's result"):
        metric.plot([first, {k: v for k, v in first.items() if k != "ave"}], keys=["ave"])


def test_the_metrics_beyond_torchmeshmetric_metrics_plot_too(tmp_path):
    """``TemporalConsistency`` (nested result: every set's RMSE) and ``MpegPSNR`` (its two PSNRs)."""
    from tests.evaluation.eval_helpers import TranslationRegister, sphere
    from torchmeshmetric.evaluation import TemporalConsistency
    from torchmeshmetric.mpeg.comparison.metric import MpegPSNR

    tc = TemporalConsistency(registration_fn=TranslationRegister())
    tc.update(sphere(1, offset=(0.1, 0, 0)), sphere(2, offset=(0.1, 0, 0)), sphere(2))
    fig, ax = tc.plot()
    out = tc.compute()
    labels = [t.get_text() for t in ax.get_xticklabels()]
    assert labels[:4] == ["surface_k_minus_1/rmse", "surface_k/rmse", "vertex_k_minus_1/rmse", "vertex_k/rmse"]
    assert "reverse/surface_k/rmse" in labels
    assert ax.patches[1].get_height() == pytest.approx(float(out["surface_k"]["rmse"]), rel=1e-12)
    assert _saved(fig, tmp_path, "tc")[:8] == PNG

    mpeg = MpegPSNR(sampling="mesh")
    a = trimesh.creation.icosphere(2)
    mpeg.update(a.copy().apply_scale(1.01), a)
    fig, ax = mpeg.plot()
    assert [t.get_text() for t in ax.get_xticklabels()] == ["d1_psnr", "d2_psnr"]
    assert ax.patches[0].get_height() == pytest.approx(float(mpeg.compute()["d1_psnr"]), rel=1e-12)
    assert _saved(fig, tmp_path, "mpeg")[:8] == PNG


def test_values_that_are_not_finite_are_labelled_and_named(tmp_path):
    # matplotlib drew a NaN bar with no label at all and left NaN / inf points off the curves without a word.
    metric = DistanceStatisticsMetric()
    result = {"ave": torch.tensor(float("nan")), "rmse": torch.tensor(2.0), "max": torch.tensor(float("inf"))}
    named = r"DistanceStatisticsMetric.plot: ave=nan, max=inf not finite: each is a label over no bar"
    with pytest.warns(UserWarning, match=named):
        fig, ax = metric.plot(result)
    # the labels keep the tables' digits: RMSE 2 significant ("2" with the old ".3g": review A, finding 9)
    assert [t.get_text() for t in ax.texts] == ["nan", "2.0", "inf"]
    assert [p.get_height() for p in ax.patches] == [0.0, 2.0, 0.0] and ax.get_ylim()[0] == 0.0
    assert _saved(fig, tmp_path, "bars")[:8] == PNG
    steps = [{"ave": torch.tensor(1.0)}, {"ave": torch.tensor(float("inf"))}]
    with pytest.warns(UserWarning, match=r"ave\[1\]=inf not finite: the curves have no point there"):
        metric.plot(steps, keys=["ave"])
    with pytest.warns(UserWarning, match=r"val\[0\]=nan not finite"):
        metric.plot([torch.tensor(float("nan")), torch.tensor(1.0)])
    with pytest.warns(UserWarning, match=r": val=-inf not finite"):
        metric.plot(torch.tensor(float("-inf")))
    plt.close("all")


def test_bar_labels_print_the_digits_the_reports_call_determined():
    # every bar was labelled with ".3g" ("1.58"), while the tables print 2 significant digits of Ave/STD/RMSE/P95,
    # 3 of Max and one decimal of a PSNR (COLUMN_FORMATS) (review A, finding 9)
    metric = DistanceStatisticsMetric()
    metric.update(torch.tensor([1.0, 2.0]))
    fig, ax = metric.plot(keys=["ave", "std", "rmse", "median", "p95", "max", "min"])
    assert [t.get_text() for t in ax.texts] == ["1.5", "0.50", "1.6", "1.5", "1.9", "2.00", "1.00"]  # p95 1.95
    plt.close(fig)
    two = _updated(MeshSurfaceDistance, two_sided=True)
    out = two.compute()
    fig, ax = two.plot(keys=["reverse_rmse", "hausdorff", "symmetric_rmse", "psnr", "count"])
    assert [t.get_text() for t in ax.texts] == [
        f"{float(out['reverse_rmse']):#.2g}",
        f"{float(out['hausdorff']):#.3g}",
        f"{float(out['symmetric_rmse']):#.2g}",
        f"{float(out['psnr']):.1f}",
        f"{float(out['count']):.0f}",
    ]
    plt.close(fig)
    # TemporalConsistency's flattened keys: a set through the registration prints its table rows' digits, the same as
    # frame k's since the registration draws independently of the storage order (review L, finding 1)
    assert [
        bar_label("surface_k_minus_1/ave", 0.0123),
        bar_label("reverse/flicker/max", 0.0859),
        bar_label("registration/residual/psnr", 42.41),
        bar_label("vertex_k_minus_1/median", 0.0315),
        bar_label("reverse/vertex_k/max", 0.0859),
        bar_label("surface_k/ave", 0.0123),
    ] == ["0.012", "0.0859", "42.4", "0.032", "0.0859", "0.012"]


def test_views_are_named_by_their_statistic(tmp_path):
    # the views of statistics() were all labelled "SelectedStatistic", the warning too (review A, finding 7)
    m = MeshSurfaceDistance(two_sided=True)
    m.update(trimesh.creation.icosphere(subdivisions=1), trimesh.creation.icosphere(subdivisions=3))
    drawn = m.statistics(["rmse", "psnr", "hausdorff"], prefix="val/$a_$").plot()  # a "$" drawn as written
    labels = sorted(ax.get_ylabel() for _, ax in drawn)
    assert labels == ["val/\\$a_\\$hausdorff", "val/\\$a_\\$psnr", "val/\\$a_\\$rmse"]
    for fig, _ in drawn:
        assert _saved(fig, tmp_path, "view")[:8] == PNG
    assert m.statistic("rmse").plot()[1].get_ylabel() == "rmse"
    eq = MeshSurfaceDistance()
    sphere = trimesh.creation.icosphere(subdivisions=1)
    eq.update(sphere, sphere)
    with pytest.warns(UserWarning, match=r"^psnr\.plot: val=inf not finite"):
        eq.statistic("psnr").plot()
    plt.close("all")


@pytest.mark.parametrize(
    ("val", "message"),
    [
        ("abc", r"val: expected a result \(a dict of statistics\), a scalar .* found str 'abc'"),
        ((x for x in [1.0]), "val: expected a result .* found generator"),
        ({"ave": torch.tensor([1.0, 2.0]), "max": 1.0},
         r"val\['ave'\]: expected a number or a one-element tensor, found a tensor of shape \(2,\)"),
        ([{"ave": 1.0, "max": 1.0}, {"ave": "x", "max": 1.0}],
         r"val\[1\]\['ave'\]: expected a number or a one-element tensor, found str 'x'"),
        (torch.ones(2, 2), r"val: expected a number or a one-element tensor, found a tensor of shape \(2, 2\)"),
        ([torch.tensor(1.0), {"ave": 1.0}], "val: expected a list of results .* found a list mixing both"),
        ([torch.tensor(1.0), "x"], r"val\[1\]: expected a number or a one-element tensor, found str 'x'"),
    ],
)  # fmt: skip
def test_val_of_no_accepted_form_is_refused_naming_val(val, message):
    # these reached torchmetrics or matplotlib and failed there, without naming val (review A, finding 6)
    metric = _updated(DistanceStatisticsMetric)
    with pytest.raises(ValueError, match=message):
        metric.plot(val)
    plt.close("all")


def test_numbers_are_accepted_where_tensors_are():
    # [1.0, 2.0] and [{"ave": 1}, {"ave": 2}] failed in torch.stack, while {"ave": 1.0} was drawn (review A, 6)
    metric = _updated(DistanceStatisticsMetric)
    _, ax = metric.plot([1.0, 2.0])
    assert [float(y) for y in ax.get_lines()[0].get_ydata()] == [1.0, 2.0]
    _, ax = metric.plot([{"ave": 1}, {"ave": 2}], keys=["ave"])
    assert [float(y) for y in ax.get_lines()[0].get_ydata()] == [1.0, 2.0]
    plt.close("all")


def _steps() -> list[dict[str, torch.Tensor]]:
    metric = DistanceStatisticsMetric(two_sided=True)
    out = []
    for batch in ([1.0, 2.0], [3.0, 5.0], [0.5]):
        metric.update(torch.tensor(batch), torch.tensor([0.25]))
        out.append(metric.compute())
    return out


_KINDS = {  # every form plot() draws on a new figure: bars (few, and tilted names), curves of dicts, of scalars
    "bars": lambda: _updated(MeshSurfaceDistance).plot(),
    "tilted bars": lambda: _updated(MeshSurfaceDistance, two_sided=True).plot(),
    "curves": lambda: DistanceStatisticsMetric(two_sided=True).plot(_steps()),
    "scalar": lambda: _updated(SelectedStatistic).plot(),
    "scalar steps": lambda: _updated(SelectedStatistic).plot([torch.tensor(0.5), torch.tensor(0.25)]),
}


@pytest.mark.parametrize("kind", list(_KINDS))
def test_saved_figure_holds_every_label(kind, tmp_path):
    # review O (F-plot-clip): the two-sided bars' tilted names ran off the bottom of a saved figure ("_ave", "dorff")
    fig, ax = _KINDS[kind]()
    tilted = kind == "tilted bars"
    assert tilted == any(t.get_rotation() != 0 for t in ax.get_xticklabels())
    fig.savefig(tmp_path / "figure.png")  # laid out and drawn as a user's savefig draws it (Agg)
    renderer = fig.canvas.get_renderer()
    # what is drawn (tick labels, axis labels, bar labels, legend, notes), not tick objects outside the view
    drawn, box = ax.get_tightbbox(renderer), fig.bbox
    cut = [t.get_text() for t in ax.get_xticklabels() if t.get_window_extent(renderer).y0 < box.y0]
    assert drawn.x0 >= box.x0 - 0.5 and drawn.y0 >= box.y0 - 0.5, (kind, drawn.bounds, box.bounds, cut)
    assert drawn.x1 <= box.x1 + 0.5 and drawn.y1 <= box.y1 + 0.5, (kind, drawn.bounds, box.bounds)
    plt.close(fig)
