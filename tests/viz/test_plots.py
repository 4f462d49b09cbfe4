import pytest

pytest.importorskip("matplotlib")

from tests.evaluation.eval_helpers import TranslationRegister, sphere
from torchmeshmetric.evaluation import evaluate_sequence
from torchmeshmetric.viz import plot_frame_curves, plot_histograms


def test_plots_are_png_and_atomic(tmp_path):
    original = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(3)]
    simplified = [sphere(0, offset=(0.1 * k, 0, 0)) for k in range(3)]
    seq = evaluate_sequence(original, simplified, registration_fn=TranslationRegister())
    h = plot_histograms({"a": seq.pairs[0], "b": seq.pairs[0]}, tmp_path / "h.png")
    c = plot_frame_curves({"a": seq}, tmp_path / "c.png", statistic="rmse")
    for p in (h, c):
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(FileExistsError):
        plot_frame_curves({"a": seq}, c)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.png", "h.png"]


def test_histograms_show_the_distribution_on_a_log_axis():
    import numpy as np
    import torch

    from torchmeshmetric import Mesh
    from torchmeshmetric.evaluation import evaluate_pair
    from torchmeshmetric.viz import plots
    from torchmeshmetric.viz.plots import histogram_figure, log_bins

    ref = sphere(3)
    verts = ref.verts.clone()
    n = verts.shape[0]
    # most vertices on the surface (distance 0), a tail over four decades: the frame-k sets of a simplification
    moved = torch.arange(0, n, 10)
    verts[moved] *= 1 + torch.logspace(-5, -1, moved.numel(), dtype=verts.dtype)[:, None]
    pair = evaluate_pair(Mesh(verts, ref.faces), ref, ref, precomputed_registration=ref)
    fig = histogram_figure({"m": pair}, bins=40)
    values = pair.distances["surface_k"].double().numpy()
    linear_counts = np.histogram(values, bins=np.linspace(0, values.max(), 41))[0]
    assert linear_counts[0] >= 0.9 * n  # the linear view: one bar at zero
    for ax in fig.axes:
        assert ax.get_xscale() == "log"
        heights = np.array([patch.get_height() for patch in ax.patches])
        assert heights.sum() == moved.numel()  # the moved vertices, resolved over the bins
        assert (heights > 0).sum() >= 25
        assert heights.max() <= 0.1 * moved.numel()
    legend = fig.axes[0].get_legend().get_texts()[0].get_text()
    assert f"{(n - moved.numel()) / n:.1%} of vertices below" in legend
    # The RMSE with the report tables' digits: those the input determines (COLUMN_FORMATS: 2 significant), for frame k
    # and for a set through the registration alike (float64, canonical sampling; review L, finding 1). The first panel
    # is the k-1 set.
    titles = {v: k for k, v in plots._LABELS.items()}
    assert {"surface_k", "surface_k_minus_1"} <= {titles[ax.get_title()] for ax in fig.axes}  # both kinds checked
    for ax in fig.axes:
        name = titles[ax.get_title()]
        d = (pair.distances[name] if name != "registration" else pair.registration_residual).double().numpy()
        rmse = float(np.sqrt(np.mean(d * d)))
        want = f"{rmse:#.2g}"
        assert f"m (RMSE {want};" in ax.get_legend().get_texts()[0].get_text(), name
    edges = log_bins([values], 40)
    assert edges[0] == pytest.approx(values[values > 0].min()) and edges[-1] == pytest.approx(values.max())


def test_log_bins_of_all_zero_distances_are_a_valid_axis():
    import numpy as np

    from torchmeshmetric.viz.plots import log_bins

    edges = log_bins([np.zeros(5)], 4)
    assert len(edges) == 5 and np.all(np.diff(edges) > 0) and edges[0] > 0
    edges = log_bins([np.array([0.0, 1e-30, 1.0])], 3)  # the axis spans at most 6 decades
    assert edges[0] == pytest.approx(1e-6) and edges[-1] == 1.0


def test_plots_have_a_flicker_and_a_registration_panel_when_flicker_was_measured(tmp_path):
    import struct

    from torchmeshmetric.evaluation import evaluate_pair

    original = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(3)]
    simplified = [sphere(0, offset=(0.1 * k, 0, 0)) for k in range(3)]
    seq = evaluate_sequence(original, simplified, registration_fn=TranslationRegister())
    # a pair alone: no flicker set
    alone = evaluate_pair(simplified[1], original[1], original[0], precomputed_registration=original[0])

    def width(path):
        return struct.unpack(">I", path.read_bytes()[16:20])[0]  # PNG IHDR

    six = plot_histograms({"a": seq.pairs[0]}, tmp_path / "six.png")
    four = plot_histograms({"a": alone}, tmp_path / "four.png")
    assert (width(six), width(four)) == (1650, 1100)  # 3 x 5 in and 2 x 5 in at 110 dpi
    assert width(plot_frame_curves({"a": seq}, tmp_path / "curves.png")) == 1650


def test_panels_of_equal_or_zero_distances_span_their_bins_without_a_warning(tmp_path):
    """Frame k-1 given as its own registration: the coarse sphere's vertices are vertices of the fine one, so every
    nearest-vertex distance to k is 0 (no bar) and to k-1 is the translation 0.1 (two values one ulp apart). Each
    panel spans its bins on the log axis; before, the ulp-wide bins made matplotlib warn of identical limits."""
    import warnings

    import numpy as np

    from torchmeshmetric.evaluation import evaluate_pair
    from torchmeshmetric.viz.plots import histogram_figure, log_bins

    original = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(2)]
    pair = evaluate_pair(sphere(0, offset=(0.1, 0, 0)), original[1], original[0], precomputed_registration=original[0])
    zeros, tenths = pair.distances["vertex_k"].numpy(), pair.distances["vertex_k_minus_1"].numpy()
    assert zeros.max() == 0 and 0 < tenths.max() - tenths.min() <= 2 * np.spacing(0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = histogram_figure({"a": pair})
        plot_histograms({"a": pair}, tmp_path / "h.png")
    panels = {ax.get_title(): ax for ax in fig.axes}
    empty, equal = panels["nearest vertex distance to k"], panels["nearest vertex distance to registered k-1"]
    assert empty.get_xscale() == "log" and empty.get_xlim() == pytest.approx((1e-6, 1.0), rel=1e-12)
    assert all(bar.get_height() == 0 for bar in empty.patches)  # every vertex is below the lowest edge
    assert "100.0% of vertices below 1e-06" in empty.get_legend().get_texts()[0].get_text()
    assert equal.get_xlim() == pytest.approx((tenths.max() / 10, tenths.max()), rel=1e-12)
    assert sum(bar.get_height() for bar in equal.patches) == len(tenths)  # every vertex in the top bin
    # a spread of a millionth or more is shown as it is
    assert log_bins([np.array([1.0, 1.0 + 1e-5])], 2).tolist() == pytest.approx([1.0, 1.0 + 5e-6, 1.0 + 1e-5])


NAMES = ["a_$b_$c", "budget $5 to $10", "$\\frac$", "x\\$y"]  # mathtext errors, math italics, an escaped dollar


def _shown(text) -> str:
    """What matplotlib draws of a Text: its string after mathtext's preprocessing (must not be parsed as math)."""
    shown, is_math = text._preprocess_math(text.get_text())
    assert not is_math, text.get_text()
    return shown


def test_user_names_in_figures_are_drawn_as_written_not_as_mathtext():
    # "a_$b_$c" (a folder name evaluate takes as the method's) made --html fail after the whole evaluation with
    # "error: b_", and "budget $5 to $10" was drawn as math italics "budget 5 to 10" (review A, finding 2).
    from types import SimpleNamespace

    from torchmeshmetric.viz.html_report import report_figures
    from torchmeshmetric.viz.plots import frame_curves_figure, histogram_figure, mpeg_figure, png_bytes

    original = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(3)]
    simplified = [sphere(0, offset=(0.1 * k, 0, 0)) for k in range(3)]
    seq = evaluate_sequence(original, simplified, registration_fn=TranslationRegister())
    pairs = [p.as_dict() for p in seq.pairs]
    rows = [{"frame": float(k), "d1_psnr": 60.0 + k, "d2_psnr": 70.0} for k in range(3)]
    mpeg = SimpleNamespace(frame_rows=lambda: rows)
    figures = [
        histogram_figure({n: seq.pairs[0] for n in NAMES}),
        frame_curves_figure({n: pairs for n in NAMES}),
        mpeg_figure({n: mpeg for n in NAMES}),
    ]
    for fig in figures:
        assert png_bytes(fig)[:4] == b"\x89PNG"  # drawn: the old labels raised a mathtext ParseException here
        for ax in fig.axes:
            shown = [_shown(t) for t in ax.get_legend().get_texts()]
            assert [s.split(" (RMSE")[0] for s in shown] == NAMES
    # the page of a report whose methods have such names, and a CTC column's title
    report = {"methods": {n: {"pairs": pairs} for n in NAMES}}
    assert len(report_figures(report)) == 1
    ((_, png),) = report_figures({"frames": [{"frame": 0, "$x_$": 1.0}, {"frame": 1, "$x_$": 2.0}]})
    assert png[:4] == b"\x89PNG"


def test_rd_curves_draw_the_codecs_names_as_written(tmp_path):
    from torchmeshmetric.viz.rd_curves import plot_rd_curves

    rows = [{side: {"rate_mbps": r, "GridD1": 60.0 + r} for side in ("anchor", "test")} for r in (1.0, 2.0)]
    path = plot_rd_curves({"rates": rows}, tmp_path / "rd.png", names=("a_$b_$", "$5"), title="seq_$x_$")
    assert path.read_bytes()[:4] == b"\x89PNG"  # the names were parsed as mathtext: "a_$b_$" failed to draw
