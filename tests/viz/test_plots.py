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


def test_plots_have_a_flicker_and_a_registration_panel_when_flicker_was_measured(tmp_path):
    import struct

    from torchmeshmetric.evaluation import evaluate_pair

    original = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(3)]
    simplified = [sphere(0, offset=(0.1 * k, 0, 0)) for k in range(3)]
    seq = evaluate_sequence(original, simplified, register=TranslationRegister())
    alone = evaluate_pair(simplified[1], original[1], original[0], registration=original[0])  # no flicker set

    def width(path):
        return struct.unpack(">I", path.read_bytes()[16:20])[0]  # PNG IHDR

    six = plot_histograms({"a": seq.pairs[0]}, tmp_path / "six.png")
    four = plot_histograms({"a": alone}, tmp_path / "four.png")
    assert (width(six), width(four)) == (1650, 1100)  # 3 x 5 in and 2 x 5 in at 110 dpi
    assert width(plot_frame_curves({"a": seq}, tmp_path / "curves.png")) == 1650
