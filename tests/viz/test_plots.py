import pytest

pytest.importorskip("matplotlib")

from tests.evaluation.eval_helpers import TranslationRegister, sphere
from torchmeshmetric.evaluation import evaluate_sequence
from torchmeshmetric.viz import plot_frame_curves, plot_histograms


def test_plots_are_png_and_atomic(tmp_path):
    original = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(3)]
    simplified = [sphere(0, offset=(0.1 * k, 0, 0)) for k in range(3)]
    seq = evaluate_sequence(original, simplified, register=TranslationRegister())
    h = plot_histograms({"a": seq.pairs[0], "b": seq.pairs[0]}, tmp_path / "h.png")
    c = plot_frame_curves({"a": seq}, tmp_path / "c.png", statistic="rmse")
    for p in (h, c):
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(FileExistsError):
        plot_frame_curves({"a": seq}, c)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.png", "h.png"]
