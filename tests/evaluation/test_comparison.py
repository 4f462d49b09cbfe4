"""Comparisons with confidence: paired t intervals over frame pairs, verdicts, noise floors, generic statistics."""

import math

import pytest
import torch

from torchmeshmetric.data import demo_sequence
from torchmeshmetric.evaluation import compare_methods, comparison_markdown, evaluate_sequence, paired_t_interval
from torchmeshmetric.evaluation.comparison import t_quantile
from torchmeshmetric.evaluation.distortions import (
    ground_truth_registrations,
    normal_offset,
    tracked_simplification,
)
from torchmeshmetric.simplification import simplify_qem

# Student t quantiles from a printed table (NIST/SEMATECH e-Handbook, Table of t critical values): an outside oracle.
T_TABLE = {(0.975, 1): 12.706, (0.975, 4): 2.776, (0.975, 9): 2.262, (0.975, 30): 2.042, (0.995, 10): 3.169}


@pytest.mark.parametrize(("p", "df"), list(T_TABLE))
def test_t_quantile_matches_the_printed_table(p, df):
    assert t_quantile(p, df) == pytest.approx(T_TABLE[(p, df)], abs=5e-4)


def test_t_quantile_matches_scipy():
    stats = pytest.importorskip("scipy.stats")  # a benchmark peer, optional
    for df in (1, 2, 3, 5, 17, 100, 1000):
        for p in (0.6, 0.9, 0.975, 0.999):
            assert t_quantile(p, df) == pytest.approx(float(stats.t.ppf(p, df)), rel=1e-10)


def test_paired_t_interval_known_answer():
    mean, lo, hi = paired_t_interval([1.0, 2.0, 3.0])  # sd 1, n 3: half-width t(0.975, 2) / sqrt(3)
    assert mean == 2.0 and hi - mean == pytest.approx(4.302653 / math.sqrt(3), rel=1e-6)
    assert mean - lo == pytest.approx(hi - mean, rel=1e-12)
    assert paired_t_interval([5.0])[1:] == (-math.inf, math.inf)  # one unit: no interval
    with pytest.raises(ValueError, match="differences"):
        paired_t_interval([])


def _method(values, residual=0.0, extra=None):
    """A method as its JSON report part: one pair per value, sets surface_k and surface_k_minus_1 equal to it."""
    pairs = []
    for k, v in enumerate(values, start=1):
        stats = {"ave": v, "rmse": v, "max": v, "p95": v, "count": 10}
        pair = {"frame": k, "surface_k": dict(stats), "surface_k_minus_1": dict(stats)}
        pair["registration"] = {"residual": {"ave": residual, "rmse": residual, "max": residual, "p95": residual}}
        pair.update(extra(k) if extra else {})
        pairs.append(pair)
    return {"pairs": pairs}


def test_verdicts_floor_and_direction():
    a = _method([1.0, 1.1, 0.9, 1.05, 0.95], residual=0.5)
    b = _method([1.2, 1.31, 1.1, 1.24, 1.16], residual=0.5)  # b is 0.2 worse on every pair
    out = compare_methods({"A": a, "B": b})["A vs B"]
    k = out["surface_k"]["ave"]
    assert k["difference"] == pytest.approx(-0.202) and k["ci95"][1] < 0 and k["verdict"] == "A better"
    assert "noise_floor" not in k
    km1 = out["surface_k_minus_1"]["ave"]  # the same difference, below the registration's residual of 0.5
    assert km1["ci95"] == k["ci95"] and km1["verdict"] == "inconclusive" and km1["noise_floor"] == 0.5
    assert set(out["surface_k"]) == {"ave", "rmse", "max", "p95"}  # count is not a quality statistic
    swapped = compare_methods({"B": b, "A": a})["B vs A"]["surface_k"]["ave"]
    assert swapped["verdict"] == "A better" and swapped["difference"] == pytest.approx(0.202)
    # below the relative margin: a consistent 1 % difference is not called by default, is without the margin
    c = _method([1.01 * v for v in [1.0, 1.1, 0.9, 1.05, 0.95]])
    assert compare_methods({"A": a, "C": c})["A vs C"]["surface_k"]["ave"]["verdict"] == "inconclusive"
    assert compare_methods({"A": a, "C": c}, relative_margin=0)["A vs C"]["surface_k"]["ave"]["verdict"] == "A better"


def test_generic_over_the_statistics_a_pair_carries_psnr_is_higher_better():
    def mpeg(k, base):
        return {"mpeg": {"d1": {"d1_psnr": base + 0.1 * k, "d1_mse": 1.0}}}

    a = _method([1.0] * 4, extra=lambda k: mpeg(k, 60.0))
    b = _method([1.0] * 4, extra=lambda k: mpeg(k, 50.0 + 0.01 * k))
    out = compare_methods({"A": a, "B": b})["A vs B"]
    assert set(out["mpeg:d1"]) == {"d1_psnr"}  # every *psnr* statistic, d1_mse is not in the default list
    assert out["mpeg:d1"]["d1_psnr"]["verdict"] == "A better"  # higher PSNR wins
    text = comparison_markdown({"A vs B": out})
    assert "| mpeg:d1 |" in text and "A: " in text


def test_a_perfect_method_wins_the_psnr_comparison():
    # A PSNR of inf on a pair (no error) gave "nan ± inf" and "inconclusive" while Ave said the same method won
    # (found by review). One sign on every pair is a verdict; a pair both measure without error is left out (it was
    # a difference of 0 there, the interval's low end) and counted.
    def mpeg(values):
        return lambda k: {"mpeg": {"d1": {"d1_psnr": values[k - 1], "d1_mse": 1.0}}}

    a = _method([1.0] * 4, extra=mpeg([math.inf, math.inf, 70.0, math.inf]))
    b = _method([1.0] * 4, extra=mpeg([60.0, math.inf, 61.0, 62.0]))
    entry = compare_methods({"A": a, "B": b})["A vs B"]["mpeg:d1"]["d1_psnr"]
    assert entry == {"difference": math.inf, "ci95": [9.0, math.inf], "verdict": "A better", "both_inf_pairs": 1}
    assert compare_methods({"B": b, "A": a})["B vs A"]["mpeg:d1"]["d1_psnr"]["verdict"] == "A better"
    mixed = _method([1.0] * 4, extra=mpeg([50.0, math.inf, 80.0, 62.0]))  # worse on one pair, better on another
    assert compare_methods({"A": a, "M": mixed})["A vs M"]["mpeg:d1"]["d1_psnr"]["verdict"] == "inconclusive"


def test_a_psnr_inf_on_a_pair_with_the_sign_changing_is_undefined_never_nan():
    # Lossless on one pair, worse on another: the difference was nan, printed "≈: nan ± inf" and written "nan" in
    # the JSON (found by review E). No mean in dB exists: it is undefined, said in words; the rmse still compares.
    def mpeg(values):
        return lambda k: {"mpeg": {"d1": {"d1_psnr": values[k - 1], "d1_mse": 1.0}}}

    a = _method([1.0, 1.0, 1.0], extra=mpeg([math.inf, 40.0, 45.0]))
    b = _method([1.0, 1.0, 1.0], extra=mpeg([60.0, 61.0, 62.0]))
    out = compare_methods({"A": a, "B": b})
    entry = out["A vs B"]["mpeg:d1"]["d1_psnr"]
    assert entry["difference"] is None and entry["ci95"] is None and entry["verdict"] == "inconclusive"
    assert "no mean difference in dB" in entry["undefined"]
    text = comparison_markdown(out)
    assert "| mpeg:d1 |  |  |  |  | ≈: undefined (PSNR inf on a pair) |" in text and "nan" not in text
    assert "no mean difference in dB exists; compare the rmse" in text


def test_a_pair_both_measure_without_error_is_left_out_of_the_psnr_difference():
    # Both lossless on a pair (PSNR inf for both) entered the interval as a difference of 0: A, 1 dB better on every
    # other pair, was "inconclusive" (mean 0.75, interval [-0.06, 1.56]); the mean difference was no longer the
    # difference of the two methods' mean PSNRs (mean_psnr leaves the inf out). The pair is left out and counted.
    from torchmeshmetric.evaluation.comparison import _compare_values
    from torchmeshmetric.stats.statistics import mean_psnr

    a, b = [math.inf, 40.0, 41.0, 42.0], [math.inf, 38.9, 40.0, 41.1]
    entry = _compare_values(a, b, "psnr", 0.0, 0.02, 0.95, ("A", "B"))
    assert entry["verdict"] == "A better" and entry["both_inf_pairs"] == 1
    assert entry["difference"] == pytest.approx(1.0, rel=1e-12)
    assert entry["difference"] == pytest.approx(mean_psnr(a)[0] - mean_psnr(b)[0], rel=1e-12)
    half = 4.302653 * 0.1 / math.sqrt(3)  # t(0.975, 2) s_d / sqrt(n) over the 3 finite pairs (s_d = 0.1)
    assert entry["ci95"] == pytest.approx([1.0 - half, 1.0 + half], rel=1e-6)
    without = _compare_values(a[1:], b[1:], "psnr", 0.0, 0.02, 0.95, ("A", "B"))
    assert {k: v for k, v in entry.items() if k != "both_inf_pairs"} == without and "both_inf_pairs" not in without
    # identical methods stay identical, every pair lossless included; a distance statistic has no such rule
    same = {"difference": 0.0, "ci95": [0.0, 0.0], "verdict": "inconclusive"}
    assert _compare_values([math.inf, 40.0], [math.inf, 40.0], "psnr", 0.0, 0.02, 0.95, ("A", "B")) == {
        **same,
        "both_inf_pairs": 1,
    }
    assert _compare_values([math.inf] * 3, [math.inf] * 3, "psnr", 0.0, 0.02, 0.95, ("A", "B")) == {
        **same,
        "both_inf_pairs": 3,
    }
    assert "both_inf_pairs" not in _compare_values(
        [math.inf, 1.0], [math.inf, 2.0], "rmse", 0.0, 0.02, 0.95, ("A", "B")
    )
    # through compare_methods and the verdict table: the count, and the note under the table
    mpeg = lambda values: lambda k: {"mpeg": {"d1": {"d1_psnr": values[k - 1], "d1_mse": 1.0}}}  # noqa: E731
    out = compare_methods({"A": _method([1.0] * 4, extra=mpeg(a)), "B": _method([1.0] * 4, extra=mpeg(b))})
    assert out["A vs B"]["mpeg:d1"]["d1_psnr"] == entry
    text = comparison_markdown(out)
    assert "| mpeg:d1 |  |  |  |  | A: 1 ± 0.248 |" in text
    assert (
        "Frame pairs both methods measure without error (PSNR inf for both), left out of that PSNR's difference and "
        "interval: mpeg:d1 d1_psnr 1" in text
    )


def test_a_pair_both_measure_without_error_leaves_the_psnr_threshold_finite():
    # review F, finding 3: the relative margin was 2 % of np.mean(a), inf with one lossless pair, so a method 9.3 dB
    # better on every other pair (interval [8.4, 10.3]) was "inconclusive"; the margin follows mean_psnr now.
    from torchmeshmetric.evaluation.comparison import _compare_values

    a = [math.inf] + [40 + 0.1 * i for i in range(20)]
    b = [math.inf] + [30 + 0.12 * i for i in range(20)]
    entry = _compare_values(a, b, "psnr", 0.0, 0.02, 0.95, ("A", "B"))
    assert entry["verdict"] == "A better" and entry["both_inf_pairs"] == 1
    # the both-inf pair is left out (it was a difference of 0, the mean over 21 pairs): the mean over the 20 others
    assert entry["difference"] == pytest.approx(sum(x - y for x, y in zip(a[1:], b[1:], strict=True)) / 20)
    assert entry["ci95"][0] > 8.0 and entry["ci95"][1] < 10.5
    # the margin is 2 % of the better finite mean (40.95 dB -> 0.819 dB), not of inf: 0.8 dB on the 20 finite pairs
    # is inconclusive, 0.9 is called
    close = [math.inf] + [x - 0.8 for x in a[1:]]
    assert _compare_values(a, close, "psnr", 0.0, 0.02, 0.95, ("A", "B"))["verdict"] == "inconclusive"
    closer = [math.inf] + [x - 0.9 for x in a[1:]]
    assert _compare_values(a, closer, "psnr", 0.0, 0.02, 0.95, ("A", "B"))["verdict"] == "A better"
    # through compare_methods: the same pairs as an MPEG PSNR
    mpeg = lambda values: lambda k: {"mpeg": {"d1": {"d1_psnr": values[k - 1], "d1_mse": 1.0}}}  # noqa: E731
    out = compare_methods({"A": _method([1.0] * 21, extra=mpeg(a)), "B": _method([1.0] * 21, extra=mpeg(b))})
    assert out["A vs B"]["mpeg:d1"]["d1_psnr"]["verdict"] == "A better"


def test_an_undefined_psnr_difference_on_the_nudged_frames_is_said_and_explained():
    # review F, finding 6: the cell read "~A: ~2 ± ~1" and the note explaining "undefined" was not printed when only
    # the nudged run's difference was undefined.
    from torchmeshmetric.evaluation.comparison import with_nudged_verdicts

    run = {"A vs B": {"mpeg:d1": {"d1_psnr": {"difference": 2.0, "ci95": [1.0, 3.0], "verdict": "A better"}}}}
    undefined = {"difference": None, "ci95": None, "verdict": "inconclusive", "undefined": "..."}
    text = comparison_markdown(with_nudged_verdicts(run, {"A vs B": {"mpeg:d1": {"d1_psnr": undefined}}}))
    assert "| mpeg:d1 | ~A: undefined on the nudged frames (PSNR inf on a pair) |" in text, text
    assert "~2" not in text and "± ~" not in text
    assert "undefined: a PSNR is inf (a pair measured without error) on some pairs" in text
    assert "on the frames nudged by --determinacy" in text and "0 of 1 the same" in text
    assert "undefined:" not in comparison_markdown(run)  # a defined run alone gets no such note


def test_methods_must_share_frame_pairs():
    with pytest.raises(ValueError, match="frame pairs"):
        compare_methods({"A": _method([1.0, 2.0]), "B": _method([1.0, 2.0, 3.0])})
    with pytest.raises(ValueError, match="two methods"):
        compare_methods({"A": _method([1.0])})


@pytest.fixture(scope="module")
def tracked():
    """The built-in sequence at a reduced size, its true registrations and a tracked QEM simplification."""
    seq = demo_sequence(5, resolution=48)
    frames = [f.to(dtype=torch.float64) for f in seq.frames]
    base = tracked_simplification(frames, simplify_qem(frames[0], 0.5), seq.transfer)
    return frames, base, ground_truth_registrations(frames, seq.transfer)


def test_constant_offset_sign_declares_no_winner_but_twice_the_offset_loses(tracked):
    """Goal: two methods that differ only by the sign of a constant normal offset (here 1e-3, about 0.05 % of the
    diagonal) get no winner on the paper's sets and flicker; an offset twice as large is caught on frame k."""
    frames, base, regs = tracked
    n = len(frames)

    def method(amount):
        return evaluate_sequence(
            frames, normal_offset(base, frames, [amount] * n), precomputed_registrations=regs, two_sided=False
        )

    plus, minus, double = method(1e-3), method(-1e-3), method(2e-3)
    out = compare_methods({"plus": plus, "minus": minus})["plus vs minus"]
    assert set(out) == {"surface_k", "surface_k_minus_1", "vertex_k", "vertex_k_minus_1", "flicker"}
    verdicts = {(s, st): e["verdict"] for s, entries in out.items() for st, e in entries.items()}
    assert set(verdicts.values()) == {"inconclusive"}, verdicts
    caught = compare_methods({"plus": plus, "double": double})["plus vs double"]
    assert caught["surface_k"]["ave"]["verdict"] == "plus better"
    assert caught["surface_k"]["ave"]["difference"] == pytest.approx(-1e-3, rel=0.02)


def test_identical_methods_every_verdict_inconclusive_every_difference_zero(tracked):
    frames, base, regs = tracked
    a = evaluate_sequence(frames, base, precomputed_registrations=regs)
    b = evaluate_sequence(frames, [m.to(dtype=torch.float64) for m in base], precomputed_registrations=regs)
    out = compare_methods({"A": a, "B": b}, relative_margin=0.0)["A vs B"]
    entries = [e for s in out.values() for e in s.values()]
    assert len(entries) >= 10 * 4 and any(k.startswith("reverse:") for k in out)
    assert all(e["verdict"] == "inconclusive" and e["difference"] == 0.0 for e in entries)
    assert all(e["ci95"] == [0.0, 0.0] for e in entries)


def test_verdicts_on_nudged_frames_mark_the_cells_they_change():
    from torchmeshmetric.evaluation.comparison import with_nudged_verdicts

    def table(ave: str, rmse: str, rmse_difference: float = -0.5) -> dict:
        entry = {"difference": -0.5, "ci95": [-0.75, -0.25]}
        rmse_entry = {"difference": rmse_difference, "ci95": [rmse_difference - 0.25, rmse_difference + 0.25]}
        return {"A vs B": {"surface_k": {"ave": {**entry, "verdict": ave}, "rmse": {**rmse_entry, "verdict": rmse}}}}

    run, again = table("A better", "A better"), table("inconclusive", "A better", rmse_difference=-0.45)
    marked = with_nudged_verdicts(run, again)
    assert marked["A vs B"]["surface_k"]["ave"]["nudged_verdict"] == "inconclusive"
    assert marked["A vs B"]["surface_k"]["rmse"]["nudged_difference"] == -0.45
    assert "nudged_verdict" not in run["A vs B"]["surface_k"]["ave"]  # a copy: the run's own dict is untouched
    text = comparison_markdown(marked)
    # ave: the same numbers in both runs, every digit of the format holds; rmse: the difference moved by 10 %
    # (one digit holds), the half-width not at all.
    assert "| surface_k | ~A: -0.500 ± 0.250 | A: -0.5 ± 0.250 |" in text
    assert "Verdicts on the frames nudged by --determinacy: 1 of 2 the same; ~ marks a verdict" in text
    plain = comparison_markdown(run)
    assert "~" not in plain and "nudged" not in plain
    # No noise floor in either run: none is listed, and no entry gets a nudged one.
    assert "noise floor (" not in text and "nudged_noise_floor" not in marked["A vs B"]["surface_k"]["ave"]
    # An entry the nudged run lacks keeps no nudged verdict and is not marked.
    assert "nudged_verdict" not in with_nudged_verdicts(run, {"A vs B": {}})["A vs B"]["surface_k"]["ave"]


def test_nudged_psnr_difference_keeps_decimals_as_the_tables_psnr():
    from torchmeshmetric.evaluation.comparison import with_nudged_verdicts

    def table(difference: float) -> dict:
        entry = {"difference": difference, "ci95": [difference - 2e-5, difference + 2e-5], "verdict": "B better"}
        return {"A vs B": {"reverse:surface_k": {"psnr": entry}}}

    # dB: the difference moved by 0.04 dB keeps one decimal (an absolute change, as the tables' PSNR), not the
    # "~-1e+01" a relative rule would print; the half-width is the same in both runs and keeps 3 digits.
    text = comparison_markdown(with_nudged_verdicts(table(-12.93), table(-12.89)))
    assert "| reverse:surface_k | B: -12.9 ± 2.00e-05 |" in text
    # -12.93 and -11.5 dB: not even the units agree (-13, -12): '~' and their midpoint's, the text both runs print
    # (it was the run's own "~-13" before review L's finding 3)
    text = comparison_markdown(with_nudged_verdicts(table(-12.93), table(-11.5)))
    assert "| reverse:surface_k | B: ~-12 ± 2.00e-05 |" in text


def test_nudged_noise_floor_keeps_the_digits_both_runs_share():
    from torchmeshmetric.evaluation.comparison import with_nudged_verdicts

    def table(floor: float, psnr_floor: float) -> dict:
        entry = {"difference": -0.5, "ci95": [-0.75, -0.25], "verdict": "A better"}
        return {
            "A vs B": {
                "surface_k_minus_1": {
                    "rmse": {**entry, "noise_floor": floor},
                    "psnr": {**entry, "difference": 0.5, "ci95": [0.25, 0.75], "noise_floor": psnr_floor},
                }
            }
        }

    # The residual floor moved by 2 % (one digit holds), the PSNR one (a few thousandths of a dB) not at all: a
    # floor is a threshold, so it keeps significant digits by its relative change, the dB one too.
    marked = with_nudged_verdicts(table(0.0123456, 0.00312), table(0.0126, 0.00312))
    entry = marked["A vs B"]["surface_k_minus_1"]["rmse"]
    assert entry["noise_floor"] == 0.0123456 and entry["nudged_noise_floor"] == 0.0126
    text = comparison_markdown(marked)
    assert "surface_k_minus_1: rmse 0.01, psnr 0.00312" in text
    assert "Differences, half-widths and noise floors keep the digits both runs share" in text
    # A floor whose first digit moved is marked; without a nudged run, 3 significant digits as before.
    assert "surface_k_minus_1: rmse ~0.02," in comparison_markdown(  # 0.0123 and 0.0223: the midpoint's digit
        with_nudged_verdicts(table(0.0123, 0.00312), table(0.0223, 0.00312))
    )
    assert "surface_k_minus_1: rmse 0.0123, psnr 0.00312" in comparison_markdown(table(0.0123456, 0.00312))


def test_a_pipe_in_a_winners_name_keeps_the_verdict_tables_columns():
    # The winner of a verdict cell was written unescaped: "a|b: -0.2 ± ..." split its row into one cell more than
    # the header had, and the page showed each statistic under the next one's column (review A, finding 1).
    from torchmeshmetric.viz.html_report import _cells, markdown_html

    a = _method([1.0, 1.1, 0.9, 1.05, 0.95])
    b = _method([1.2, 1.31, 1.1, 1.24, 1.16])
    text = comparison_markdown(compare_methods({"a|b\nx": a, "B": b}))
    rows = [line for line in text.splitlines() if line.startswith("|") and not line.startswith("|---")]
    header = _cells(rows[0])
    assert header == ["set", "ave", "rmse", "max", "p95"]
    assert all(len(_cells(r)) == len(header) for r in rows[1:])
    surface_k = next(_cells(r) for r in rows if r.startswith("| surface_k |"))
    assert surface_k[1] == "a|b x: -0.202 ± 0.0104"  # the ave column holds the ave difference (t interval)
    assert text.startswith("### a\\|b x vs B (difference")  # the heading: one line
    assert "<td>a|b x: -0.202 ± 0.0104</td>" in markdown_html(text)


def test_markdown_emphasis_in_a_method_name_is_shown_as_written():
    # "**a**" in a verdict cell or the heading showed as a bold "a", "_b_" as an italic "b" (markdown_cell escaped
    # only "|" and "\\"); the page's cell is the name as typed.
    from torchmeshmetric.viz.html_report import markdown_html

    a = _method([1.0, 1.1, 0.9, 1.05, 0.95])
    b = _method([1.2, 1.31, 1.1, 1.24, 1.16])
    text = comparison_markdown(compare_methods({"**a**": a, "_b_": b}))
    assert text.startswith("### \\*\\*a\\*\\* vs \\_b\\_ (difference")
    assert "| surface_k | \\*\\*a\\*\\*: -0.202 ± 0.0104 |" in text
    page = markdown_html(text)
    assert "<td>**a**: -0.202 ± 0.0104</td>" in page and "<strong>" not in page
