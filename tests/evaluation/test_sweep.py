"""The Registered QEM weight sweep (API, Pareto front, plot) on a tiny sequence."""

import pytest
import torch

from tests.evaluation.eval_helpers import TranslationRegister, sphere
from torchmeshmetric.evaluation import evaluate_sequence, registered_qem_sweep
from torchmeshmetric.evaluation.sweep import SWEEP_DIGITS_NOTE, pareto_front
from torchmeshmetric.simplification import simplify_sequence


@pytest.fixture(scope="module")
def spheres():
    frames = [sphere(3, offset=(0.1 * k, 0, 0)) for k in range(3)]
    register = TranslationRegister()
    regs = [register(frames[k - 1], frames[k]) for k in (1, 2)]
    return frames, regs


def test_sweep_rows_are_the_evaluations_of_each_weight_and_of_plain_qem(spheres, tmp_path):
    frames, regs = spheres
    done = []
    sweep = registered_qem_sweep(frames, regs, 0.3, [0.0, 3.0], progress=done.append)
    assert done == [0.0, 3.0] and sweep.weights == [0.0, 3.0] and sweep.baseline is not None
    rows = sweep.rows()
    assert [r["weight"] for r in rows] == [0.0, 3.0, None]
    for weight, row in zip((0.0, 3.0), rows, strict=False):
        simplified = simplify_sequence(frames, 0.3, registrations=regs, weight=weight)
        expect = evaluate_sequence(frames, simplified, precomputed_registrations=regs, two_sided=False).aggregate()
        assert row == {"weight": weight, **{s: expect[s]["ave"] for s in ("surface_k", "surface_k_minus_1", "flicker")}}
    qem = evaluate_sequence(
        frames, simplify_sequence(frames, 0.3), precomputed_registrations=regs, two_sided=False
    ).aggregate()
    assert rows[-1]["surface_k"] == qem["surface_k"]["ave"]
    table = sweep.markdown()
    assert table.count("| Registered QEM |") == 2 and "| QEM (fast-simplification) |" in table

    # Only the digits the input determines, as in the paper's tables: 2 significant (COLUMN_FORMATS) for frame k and
    # for the registered k-1 and flicker columns too, since the registration draws independently of the original
    # frames' storage order (sampling="canonical"; review L, finding 1).
    def two_digits(x: float) -> str:
        return format(x, "#.2g")

    for line, row in zip(table.splitlines()[2:5], rows, strict=True):
        cells = [c.strip() for c in line.strip("|").split("|")][2:]
        want = [two_digits(row["surface_k"]), two_digits(row["surface_k_minus_1"]), two_digits(row["flicker"])]
        assert cells == want
    assert table.rstrip().endswith(SWEEP_DIGITS_NOTE)
    rmse_first = sweep.markdown("rmse").splitlines()[2]
    assert f"| {two_digits(sweep.rows('rmse')[0]['flicker'])} |" in rmse_first and "(rmse)" in sweep.markdown("rmse")
    # Max: 3 significant in every column (no '~': the storage order no longer moves the registered columns).
    max_first = [c.strip() for c in sweep.markdown("max").splitlines()[2].strip("|").split("|")][2:]
    max_row = sweep.rows("max")[0]
    assert max_first == [format(max_row[k], "#.3g") for k in ("surface_k", "surface_k_minus_1", "flicker")]
    with pytest.raises(ValueError, match=r"statistic: .*found 'min'"):
        sweep.markdown("min")
    assert set(sweep.as_dict()) == {"weights", "ave", "rmse", "registration"}
    pytest.importorskip("matplotlib")
    from torchmeshmetric.viz import plot_weight_sweep

    assert plot_weight_sweep(sweep, tmp_path / "s.png").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ValueError, match="weights"):
        registered_qem_sweep(frames, regs, 0.3, [])
    # "1" ran over its characters, and a bad weight in the middle failed after the earlier ones (found by review)
    with pytest.raises(TypeError, match=r"weights: expected a sequence of numbers, found str '1'"):
        registered_qem_sweep(frames, regs, 0.3, "1")  # type: ignore[arg-type]
    seen = []
    with pytest.raises(ValueError, match=r"weights\[1\]: expected a finite number >= 0, found -1.0"):
        registered_qem_sweep(frames, regs, 0.3, [0.0, -1.0], progress=seen.append)
    assert seen == []


def test_pareto_front():
    points = {0.0: (1.0, 5.0), 1.0: (2.0, 3.0), 2.0: (3.0, 4.0), 4.0: (4.0, 1.0), 8.0: (0.5, 9.0)}
    assert pareto_front(points) == [8.0, 0.0, 1.0, 4.0]  # 2.0 is dominated by 1.0


def test_sequence_simplifier_checks_registrations(spheres):
    frames, regs = spheres
    with pytest.raises(ValueError, match="registrations"):
        simplify_sequence(frames, 0.3, registrations=regs[:1])
    assert torch.equal(
        simplify_sequence(frames, 0.3)[0].faces, simplify_sequence(frames, 0.3, registrations=regs)[0].faces
    )
