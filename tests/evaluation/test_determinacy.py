"""The per-run determinacy (``--determinacy``): the nudge, the digits kept, the comparison of two runs."""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric import Mesh
from torchmeshmetric.evaluation.determinacy import (
    Determinacy,
    determined_cell,
    measure_determinacy,
    nudge_frames,
    relabel_frames,
    shared_cell,
    storage_unit,
    value_change,
)
from torchmeshmetric.evaluation.reports import COLUMN_FORMATS, COLUMNS


def _frame(dtype: torch.dtype) -> Mesh:
    g = torch.Generator().manual_seed(3)
    verts = (torch.rand(500, 3, generator=g, dtype=torch.float64) - 0.5) * 4
    verts[:7, 1] = 0.0  # exact zeros: a float32 storage holds them exactly
    faces = torch.randint(0, 500, (300, 3), generator=g)
    return Mesh(verts.to(dtype), faces, validate=False)


def test_float32_nudge_moves_coordinates_to_a_neighbour_at_most():
    frame = _frame(torch.float32)
    (moved,) = nudge_frames([frame], "float32")
    assert moved.verts.dtype == torch.float32 and moved.faces is frame.faces
    up = torch.nextafter(frame.verts, torch.full_like(frame.verts, math.inf))
    down = torch.nextafter(frame.verts, torch.full_like(frame.verts, -math.inf))
    v = moved.verts
    assert bool(((v == frame.verts) | (v == up) | (v == down)).all())
    # A uniform move of up to one spacing rounds to a neighbour for half of the coordinates (|step| > 1/2 ulp).
    share = (v != frame.verts).double().mean().item()
    assert 0.4 < share < 0.6, share
    assert bool((v[:7, 1] == 0).all())


def test_float64_nudge_is_continuous_and_within_one_float32_unit():
    frame = _frame(torch.float64)
    (moved,) = nudge_frames([frame], "float32", seed=5)
    step = (moved.verts - frame.verts).abs()
    _, exponent = torch.frexp(frame.verts.float().double())
    unit = torch.ldexp(torch.ones_like(frame.verts), exponent - 24)
    nonzero = frame.verts != 0
    assert bool((step[nonzero] <= unit[nonzero]).all()) and bool((step[~nonzero] == 0).all())
    assert (step[nonzero] > 0).double().mean().item() == 1.0
    # Uniform in (-1, 1) units: the mean |step| is half a unit (1500 draws: within 0.05 of it, ~4 sigma).
    assert abs((step[nonzero] / unit[nonzero]).mean().item() - 0.5) < 0.05


def test_decimal_nudge_and_seeds():
    frame = _frame(torch.float64)
    a, b = nudge_frames([frame, frame], 3, seed=1)
    again = nudge_frames([frame], "3", seed=1)[0]
    other = nudge_frames([frame], 3, seed=2)[0]
    assert float((a.verts - frame.verts).abs().max()) <= 1e-3
    assert float((a.verts - frame.verts).abs().max()) > 0.9e-3  # 1500 uniform draws reach near the bound
    assert torch.equal(a.verts, again.verts) and torch.equal(a.verts, b.verts)  # a function of the values
    assert not torch.equal(a.verts, other.verts)


def test_nudge_keeps_coincidences_as_storage_does():
    """Equal coordinates move alike, whatever their vertex, mesh or order; the axes move independently."""
    frame = _frame(torch.float32)
    perm = torch.randperm(500, generator=torch.Generator().manual_seed(1))
    doubled = Mesh(torch.cat([frame.verts, frame.verts[perm]]), frame.faces, validate=False)
    (moved,) = nudge_frames([doubled], "float32")
    assert torch.equal(moved.verts[500:], moved.verts[:500][perm])  # duplicates stay duplicates
    subset = Mesh(frame.verts[::7].clone(), frame.faces[:1] % 72, validate=False)  # kept positions of a "simplified"
    a, b = nudge_frames([frame, subset], "float32")
    assert torch.equal(b.verts, a.verts[::7])
    diagonal = Mesh(torch.full((1, 3), 0.7, dtype=torch.float64), torch.zeros(1, 3, dtype=torch.int64), validate=False)
    step = nudge_frames([diagonal], 6)[0].verts - 0.7
    assert len(set(step.flatten().tolist())) == 3  # not along the diagonal only


def test_a_unit_finer_than_the_frames_dtype_is_raised_to_it():
    from torchmeshmetric.evaluation.determinacy import raised_fraction

    # Coordinates in millimetres (|x| ~ 50-200): float32's spacing there is 3.8e-6 to 1.5e-5, so 9 decimals of a
    # float32 frame would round away entirely; the nudge moves them by float32 units instead, as "float32" does.
    frame = _frame(torch.float32)
    mm = Mesh((frame.verts.double() * 50 + 100).float(), frame.faces, validate=False)
    (moved,) = nudge_frames([mm], 9)
    assert torch.equal(moved.verts, nudge_frames([mm], "float32")[0].verts)
    assert 0.4 < (moved.verts != mm.verts).double().mean().item() < 0.6
    assert raised_fraction([mm], 9) == 1.0 and raised_fraction([mm], 4) == 0.0 and raised_fraction([mm], "float32") == 0
    # float64 frames hold 9 decimals at that scale: the nudge stays the decimal one, within 1e-9.
    mm64 = Mesh(mm.verts.double(), mm.faces, validate=False)
    step = (nudge_frames([mm64], 9)[0].verts - mm64.verts).abs()
    assert float(step.max()) <= 1e-9 and float(step.max()) > 0.9e-9 and raised_fraction([mm64], 9) == 0.0
    # Exact zeros: a decimal unit moves them (a file's 0.000000 is a rounding too), the dtype's spacing is none.
    assert raised_fraction([frame], 15) == pytest.approx(1 - 7 / 1500)


@pytest.mark.parametrize("bad", ["float16", "-1", 16, True, 2.5, "", "\u0663"])
def test_storage_unit_rejects_other_roundings(bad):
    with pytest.raises(ValueError, match=r"rounding: expected 'float32' or a number of decimals 0\.\.15"):
        storage_unit(bad)


@pytest.mark.parametrize(
    ("change", "value", "key", "cell"),
    [
        (0.0, 0.0123456, "ave", "0.012"),
        (2e-3, 0.0123456, "ave", "0.012"),  # floor(-log10(2e-3)) = 2 digits
        (0.013, 0.0123456, "ave", "0.01"),
        (0.13, 0.0123456, "ave", "~0.01"),
        (math.inf, 0.0123456, "ave", "~0.01"),
        (1e-4, 0.0859412, "max", "0.0859"),
        (5e-3, 0.0859412, "max", "0.086"),
        (0.05, 2.2e-7, "var", "2e-07"),
        (0.014, 61.274, "psnr", "61.3"),
        (0.3, 61.274, "psnr", "61"),
        (2.0, 61.274, "psnr", "~61"),
        (0.0, math.inf, "psnr", "inf"),
    ],
)
def test_cells_keep_the_determined_digits(change, value, key, cell):
    d = Determinacy("float32", 0, {"III": [{key: change}]})
    assert d.cell("III", 0, key, value, COLUMN_FORMATS[key]) == cell


def _stats(scale: float) -> dict[str, float]:
    return {k: scale * (i + 1) * 1e-3 for i, (k, _) in enumerate(COLUMNS)} | {"psnr": 60.0 * scale}


class _Stats:
    def __init__(self, scale: float):
        self.scale = scale

    def as_dict(self) -> dict[str, float]:
        return _stats(self.scale)


_SETS = [f"{kind}_{m}" for kind in ("surface", "vertex") for m in ("k", "k_minus_1")]


class _Pair:
    def __init__(self, frame, scale):
        self.frame, self.motion = frame, 0.1 * frame
        self.statistics = {name: _Stats(scale) for name in _SETS}
        self.registration_statistics = _Stats(scale)
        self.registration_error_statistics = None
        self.registration_converged = True


class _Sequence:
    """The part of SequenceEvaluation that table_rows reads, with statistics scaled by ``scale``."""

    def __init__(self, scale: float, frames=(1, 2)):
        self.pairs = [_Pair(k, scale) for k in frames]
        self.scale = scale

    def best_pair_index(self):
        return 0

    def aggregate(self):
        return {name: _stats(self.scale) for name in _SETS}

    def aggregate_reverse(self):
        return {}

    def aggregate_registration(self):
        return {"residual": _stats(self.scale)}


def test_measure_determinacy_compares_every_cell():
    d = measure_determinacy({"A": _Sequence(1.0)}, {"A": _Sequence(1.001)}, "float32")  # type: ignore[dict-item]
    assert set(d.changes) == {"I", "II", "III", "IV", "III-reverse", "IV-reverse"}
    rows = d.changes["III"]
    assert len(rows) == 3  # (k-1)-th, k-th, the registration's residual
    for row in rows:
        assert row["ave"] == pytest.approx(0.001 / 1.001, rel=1e-12)
        assert row["psnr"] == pytest.approx(0.06, rel=1e-9)  # absolute, in dB
    assert d.as_dict()["rounding"] == "float32" and d.as_dict()["changes"]["III"] == rows


def test_measure_determinacy_needs_the_same_pairs():
    with pytest.raises(ValueError, match="nudged: expected the same methods and frame pairs"):
        measure_determinacy({"A": _Sequence(1.0)}, {"B": _Sequence(1.0)}, "float32")  # type: ignore[dict-item]
    with pytest.raises(ValueError, match="nudged: expected the same methods and frame pairs"):
        measure_determinacy({"A": _Sequence(1.0)}, {"A": _Sequence(1.0, (1, 3))}, "float32")  # type: ignore[dict-item]


def test_paper_tables_print_the_determined_digits():
    from torchmeshmetric.evaluation.reports import markdown_report, paper_tables

    methods = {"A": _Sequence(1.0)}
    d = measure_determinacy(methods, {"A": _Sequence(1.05)}, "6")  # type: ignore[dict-item]
    text = paper_tables(methods, determinacy=d)  # type: ignore[arg-type]
    # Ave 0.0010 and 0.0011 (1.05e-3) share one digit; PSNR 60 and 63 dB not even the units: '~' and their
    # midpoint, 61.5 dB, with no decimal (the text both runs print; it was "~60", the run's own, before review L).
    assert "| A | k-th | 0.001 | 0.002 |" in text and "| ~62 |" in text
    assert "one unit of its storage (6 decimals, seed 0)" in text
    plain = paper_tables(methods)  # type: ignore[arg-type]
    assert "| A | k-th | 0.0010 | 0.0020 |" in plain and "| 60.0 |" in plain
    assert "(6 decimals, seed 0)" in markdown_report(methods, determinacy=d)  # type: ignore[arg-type]


@pytest.mark.pinned
def test_nudge_is_the_same_bits_on_every_machine():
    """Integer hashing and IEEE-exact float steps only: the nudge (hence --determinacy's report) is pinned."""
    mesh = Mesh(torch.tensor([[0.25, -1.5, 3.0]], dtype=torch.float64), torch.zeros(1, 3, dtype=torch.int64))
    moved = [x.hex() for x in nudge_frames([mesh], "float32")[0].verts.flatten().tolist()]
    assert moved == ["0x1.fffffd5d91647p-3", "-0x1.8000013405ec8p+0", "0x1.800000f9b5064p+1"]
    moved = [x.hex() for x in nudge_frames([mesh], 6, seed=7)[0].verts.flatten().tolist()]
    assert moved == ["0x1.0000060cef8b3p-2", "-0x1.80000dfbdcf97p+0", "0x1.800000e2963fap+1"]


def test_temporal_changes_join_the_tables_changes():
    from torchmeshmetric.evaluation.determinacy import with_temporal_changes
    from torchmeshmetric.temporal.figures import TemporalFigures
    from torchmeshmetric.temporal.report import FIGURE_DIGITS_NOTE, temporal_markdown

    tables = Determinacy("float32", 3, {"III": [{"ave": 0.01}]})
    figures = {"a": {"kg": 2.0, "sted": 0.5}, "b": {"kg": 1.0, "sted": 0.25}}
    nudged = {"a": {"kg": 2.0, "sted": 0.6}, "b": {"kg": 1.01, "sted": 0.25}}
    d = with_temporal_changes(tables, figures, nudged, ["kg", "sted"])
    assert (d.rounding, d.seed, d.changes["III"]) == ("float32", 3, [{"ave": 0.01}])
    assert d.changes["temporal"] == [
        {"kg": 0.0, "sted": abs(0.5 - 0.6) / 0.6},
        {"kg": abs(1.0 - 1.01) / 1.01, "sted": 0.0},
    ]
    with pytest.raises(ValueError, match=r"nudged: expected the methods \['a', 'b'\], found \['b', 'a'\]"):
        with_temporal_changes(tables, figures, dict(reversed(nudged.items())), ["kg"])
    # Without a "temporal" table (the tables' measurement alone), the section prints the measured fixed digits.
    f = TemporalFigures(1.23456789, 2.0, 0.1, 0.2, 0.1, False, 3, 100)
    assert temporal_markdown({"m": f}, determinacy=tables) == temporal_markdown({"m": f})
    assert FIGURE_DIGITS_NOTE in temporal_markdown({"m": f})
    measured = Determinacy("float32", 0, {"temporal": [{"kg": 2e-3, "kso": 0, "sted_s": 0, "sted_t": 0, "sted": 0.5}]})
    row = temporal_markdown({"m": f}, determinacy=measured).splitlines()[4]
    assert row == "| m | 1.2 | 2.00000 | 0.100 | 0.200000 | ~0.1 | exact |"  # STED moved by half: "~"


# Review L, finding 3: values on either side of a rounding boundary, each "determined" to 2 digits by its change
# alone, printed 9.0e-07 and 8.9e-07 (the registration residual's MSE on two CPUs) and 0.012 / 0.013.
@pytest.mark.parametrize(
    ("a", "b", "spec", "cell"),
    [
        (8.950642936687598e-07, 8.945305266957198e-07, "#.2g", "9e-07"),
        (0.012499, 0.012501, "#.2g", "0.01"),
        (0.0949, 0.0951, "#.3g", "0.095"),  # 3 digits differ, 2 agree, 1 would differ again: the most that agree
        (0.0123456, 0.0123457, "#.2g", "0.012"),
        (0.0859412, 0.0859399, "#.3g", "0.0859"),
        (2.2e-7, 2.3e-7, "#.2g", "2e-07"),
        (0.0123, 0.0283, "#.2g", "~0.02"),  # not even the first digit: '~' and the midpoint's
        (61.27, 61.36, ".1f", "61"),
        (60.9, 62.2, ".1f", "~62"),
        (61.25, 61.25, ".1f", "61.2"),  # equal values: the format's own text (round half to even)
        (math.inf, math.inf, ".1f", "inf"),
    ],
)
def test_shared_cell_prints_what_both_runs_print(a, b, spec, cell):
    assert shared_cell(a, b, spec) == cell and shared_cell(b, a, spec) == cell


def test_determinacy_cells_use_both_values():
    a, b = 8.950642936687598e-07, 8.945305266957198e-07
    run = Determinacy("float32", 0, {"I": [{"mse": value_change(a, b)}]}, {"I": [{"mse": b}]})
    other = Determinacy("float32", 0, {"I": [{"mse": value_change(b, a)}]}, {"I": [{"mse": a}]})
    assert run.cell("I", 0, "mse", a, "#.2g") == other.cell("I", 0, "mse", b, "#.2g") == "9e-07"
    # the change alone (a Determinacy without the second run's values) keeps 3 - 1 digits of each: they differ
    assert determined_cell(a, value_change(a, b), "#.2g") != determined_cell(b, value_change(a, b), "#.2g")
    assert run.as_dict()["nudged"] == {"I": [{"mse": b}]} and "nudged" not in Determinacy("6 decimals", 0, {}).as_dict()


def test_measure_determinacy_keeps_the_second_runs_values():
    d = measure_determinacy({"A": _Sequence(1.0)}, {"A": _Sequence(1.001)}, "float32")  # type: ignore[dict-item]
    assert d.nudged["III"][0] == _stats(1.001) and set(d.nudged) == set(d.changes)


_FINITE = st.floats(allow_nan=False, allow_infinity=False)


@settings(max_examples=500, deadline=None)
@given(
    a=_FINITE,
    b=_FINITE,
    spec=st.sampled_from(sorted({*COLUMN_FORMATS.values(), "#.1g", "#.3g", "#.6g", ".0f", ".2f"})),
)
def test_shared_cell_is_the_same_text_for_both_runs(a, b, spec):
    text = shared_cell(a, b, spec)
    assert text == shared_cell(b, a, spec)
    # the most digits (at most the format's) at which both values read the same; '~' where no count of them does
    significant = spec.endswith("g")
    counts = range(int(spec.rstrip("fg").split(".")[-1]), 0 if significant else -1, -1)
    agree = [d for d in counts if _text(a, d, significant) == _text(b, d, significant)]
    if agree:
        assert text == _text(a, agree[0], significant)
    else:
        assert text.startswith("~")


def _text(x: float, digits: int, significant: bool) -> str:
    if significant:
        return format(x, f"#.{digits}g").replace(".e", "e").rstrip(".")
    return format(x, f".{digits}f")


def _oriented_triangles(mesh: Mesh) -> set[tuple[tuple[float, ...], ...]]:
    """Each face as its corners' coordinates from its smallest corner on: the same for a rotation, not a flip."""
    out = set()
    for corners in mesh.verts[mesh.faces].tolist():
        i = min(range(3), key=lambda j: corners[j])
        out.add(tuple(tuple(c) for c in corners[i:] + corners[:i]))
    return out


def test_relabel_keeps_the_surfaces_and_a_shared_connectivity():
    frame = _frame(torch.float32)
    other = Mesh(frame.verts * 2, frame.faces, validate=False)  # the same connectivity (a tracked sequence)
    moved, moved_other = relabel_frames([frame, other], seed=4)
    assert _oriented_triangles(moved) == _oriented_triangles(frame) and torch.equal(moved.faces, moved_other.faces)
    assert torch.equal(moved.verts.sort(0).values, frame.verts.sort(0).values)  # the frame's own bits, moved
    assert not torch.equal(moved.faces, frame.faces) and not torch.equal(moved.verts, frame.verts)
    again = relabel_frames([frame], seed=4)[0]
    assert torch.equal(again.faces, moved.faces) and torch.equal(again.verts, moved.verts)  # a function of its input
    assert not torch.equal(relabel_frames([frame], seed=5)[0].faces, moved.faces)


@pytest.mark.pinned
def test_relabel_is_the_same_on_every_machine():
    # splitmix64 in numpy's uint64 arithmetic and a stable argsort: no torch RNG, whose streams are not promised
    frame = Mesh(torch.zeros(6, 3), torch.tensor([[0, 1, 2], [2, 3, 4], [4, 5, 0], [1, 3, 5]]), validate=False)
    assert relabel_frames([frame], seed=0)[0].faces.tolist() == [[4, 0, 3], [0, 2, 1], [2, 5, 4], [1, 5, 3]]
