"""The CTC sheet's summary against a hand-made spreadsheet case: BD figures from ``bjontegaard``, the rest by hand.

Three sequences (two of class cat1-A, one of cat1-B), three rate points, an anchor and a test codec, with bitstream
components, runtimes and memory. Every figure of :func:`ctc_summary` is recomputed here from the sheet's cell formulas
(``empty.xlsm`` of the test model: J = O*G/F/1e6, K = O/D, M = P+Q+R, L = M+S+T, BD via bdRateExtend over L / M / S,
ratios IF(B=0, 0, B/A-1), class rows AVERAGE over the class's cells, Total time [%] = SUM(B)/SUM(A)) with the
``bjontegaard`` package's pchip BD-rate on these monotone curves (equal to bdRateExtend there, tests/mpeg/test_bd_rate)
and explicit arithmetic. Tolerance: 1e-6 % on BD figures (the goal), 1e-12 relative on the arithmetic.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import replace
from pathlib import Path

import pytest

from torchmeshmetric.mpeg.ctc.sheet import (
    TEST_MODEL_COLUMNS,
    RatePoint,
    SheetCondition,
    SheetSequence,
    ctc_summary,
    format_test_model_csv,
    read_test_model_csv,
    summary_csv,
    summary_markdown,
)

METRICS = ("GridD1", "GridD2", "GridLuma", "GridChromaCb", "GridChromaCr", "IbsmGeom", "IbsmLuma")
SEQS = [
    SheetSequence(1, "longdress", "cat1-A", 32, 30.0, 11997440),
    SheetSequence(2, "soldier", "cat1-A", 32, 30.0, 11000000),
    SheetSequence(5, "mitch", "cat1-B", 32, 30.0, 9000000),
]
COND = SheetCondition(1, "C1 lossy AI")
COMP = ("mesh_intra", "mesh_inter", "displacements", "texture", "metadata")


def _point(seq: int, rate: int, scale: float, shift: float) -> RatePoint:
    """A monotone RD point: bits grow with the rate, PSNRs too (each metric its own offset)."""
    comps = {
        "mesh_intra": 2e5 * rate * scale,
        "mesh_inter": 0.0 if seq == 5 else 5e4 * rate * scale,
        "displacements": 3e5 * rate**1.2 * scale,
        "texture": 8e5 * rate**1.1 * scale * (1.1 if seq == 2 else 1),
        "metadata": 1e3,
    }
    comps = {c: float(round(v)) for c, v in comps.items()}  # bits are integers
    total = sum(comps.values()) + 4000  # the file's total has headers beyond the five components
    # each metric its own slope, offset and gain, so that no two metrics share a BD figure
    figures = {
        m: 50.0 + (4.0 + 0.3 * i) * math.log2(rate) + 0.7 * i + shift * (1 + 0.2 * i) + 0.1 * seq
        for i, m in enumerate(METRICS)
    }
    return RatePoint(
        seq, 1, rate, total, figures, 1000 * rate, 100.0 * rate * scale, 10.0 + rate, 2000.0 * scale, 900.0, comps
    )


ANCHOR = {(s.seq_id, 1, r): _point(s.seq_id, r, 1.0, 0.0) for s in SEQS for r in (1, 2, 3)}
TEST = {(s.seq_id, 1, r): _point(s.seq_id, r, 0.9, 0.15) for s in SEQS for r in (1, 2, 3)}


def _bd(bits: str, metric: str, seq: int) -> float:
    bd = pytest.importorskip("bjontegaard")

    def rate(p: RatePoint) -> float:
        c = p.components
        m = c["mesh_intra"] + c["mesh_inter"] + c["displacements"]
        return {"L": m + c["texture"] + c["metadata"], "M": m, "S": c["texture"]}[bits]

    a = [ANCHOR[seq, 1, r] for r in (1, 2, 3)]
    b = [TEST[seq, 1, r] for r in (1, 2, 3)]
    return float(
        bd.bd_rate(
            [rate(p) for p in a],
            [p.figures[metric] for p in a],
            [rate(p) for p in b],
            [p.figures[metric] for p in b],
            method="pchip",
            min_overlap=0,
        )
    )


def _close(x: float, y: float) -> bool:
    return abs(x - y) <= 1e-12 * max(1.0, abs(y))


def test_bd_figures_equal_the_sheet() -> None:
    """BD-rate (L), BD-TotGeoRate (M), BD-AttrRate (S) per sequence, class and overall means: 1e-6 %."""
    d = ctc_summary(SEQS, [COND], ANCHOR, TEST)["conditions"][0]
    for s, seq in zip(d["sequences"], SEQS, strict=True):
        for m in METRICS:
            assert abs(s["bd_rate"][m] - _bd("L", m, seq.seq_id)) < 1e-6, (seq.name, m)
        for m in ("GridD1", "GridD2", "IbsmGeom"):
            assert abs(s["bd_geometry_rate"][m] - _bd("M", m, seq.seq_id)) < 1e-6
        for m in ("GridLuma", "GridChromaCb", "GridChromaCr", "IbsmLuma"):
            assert abs(s["bd_attribute_rate"][m] - _bd("S", m, seq.seq_id)) < 1e-6
    a_cls = {c["class"]: c for c in d["classes"]}
    for m in METRICS:  # AVERAGE(AZ5:AZ14): the sequences' BD cells of the class
        assert abs(a_cls["cat1-A"]["bd_rate"][m] - (_bd("L", m, 1) + _bd("L", m, 2)) / 2) < 1e-6
        assert abs(a_cls["cat1-B"]["bd_rate"][m] - _bd("L", m, 5)) < 1e-6
        assert abs(d["overall"]["bd_rate"][m] - (_bd("L", m, 1) + _bd("L", m, 2) + _bd("L", m, 5)) / 3) < 1e-6
    assert all(v < 0 for v in d["overall"]["bd_rate"].values())  # the test codec: fewer bits, higher PSNR
    assert len({round(v, 6) for v in d["overall"]["bd_rate"].values()}) == len(METRICS)  # a mix-up would show


def test_rates_bpif_ratios_equal_the_sheet() -> None:
    """Rate [Mbps], bpif, component ratios (per rate, class mean over rate rows), time and memory SUM ratios."""
    d = ctc_summary(SEQS, [COND], ANCHOR, TEST)["conditions"][0]
    for s, seq in zip(d["sequences"], SEQS, strict=True):
        for row in s["rates"]:
            a, b = ANCHOR[seq.seq_id, 1, row["rate"]], TEST[seq.seq_id, 1, row["rate"]]
            assert _close(row["anchor"]["rate_mbps"], a.total_bits * 30.0 / 32 / 1000000)
            assert _close(row["test"]["bpif"], b.total_bits / seq.input_faces)
            for c in COMP:
                want = 0.0 if b.components[c] == 0 else b.components[c] / a.components[c] - 1
                assert _close(row["component_ratios"][c], want)
        bp = [TEST[seq.seq_id, 1, r].total_bits / seq.input_faces for r in (1, 2, 3)]
        assert _close(s["bpif"]["test"], sum(bp) / 3)
    cls_a = [(SEQS[i], r) for i in (0, 1) for r in (1, 2, 3)]
    a_cls = d["classes"][0]
    assert a_cls["class"] == "cat1-A"
    want = sum(ANCHOR[s.seq_id, 1, r].total_bits / s.input_faces for s, r in cls_a) / 6
    assert _close(a_cls["bpif"]["anchor"], want)
    ratios = [
        TEST[s.seq_id, 1, r].components["texture"] / ANCHOR[s.seq_id, 1, r].components["texture"] - 1 for s, r in cls_a
    ]
    assert _close(a_cls["component_ratios"]["texture"], sum(ratios) / 6)
    enc_b = sum(p.encoder_seconds for p in TEST.values())  # type: ignore[misc]
    enc_a = sum(p.encoder_seconds for p in ANCHOR.values())  # type: ignore[misc]
    assert _close(d["overall"]["time_ratios"]["encoder"], enc_b / enc_a)
    assert _close(d["overall"]["time_ratios"]["decoder"], 1.0)
    assert _close(d["overall"]["memory_ratios"]["encoder"], 0.9)


def test_lossless_condition_and_missing_values() -> None:
    """C0: bpif ratio = mean B bpif / mean A bpif (the sheet's V13 = P13/I13), no BD; missing split: no BD-TotGeo."""
    seq = SEQS[:1]
    a = {(1, 0, 0): RatePoint(1, 0, 0, 1000.0, components={"mesh_intra": 600.0, "mesh_inter": 100.0})}
    b = {(1, 0, 0): RatePoint(1, 0, 0, 800.0, components={"mesh_intra": 500.0, "mesh_inter": 60.0})}
    c = ctc_summary(seq, [SheetCondition(0, "C0 lossless AI", True)], a, b)["conditions"][0]
    assert _close(c["overall"]["bpif_ratio"], (800.0 / 11997440) / (1000.0 / 11997440))
    assert _close(c["sequences"][0]["mesh_ratio"], 560.0 / 700.0 - 1)
    assert "bd_rate" not in c["overall"]
    bare_a = {k: RatePoint(*k, p.total_bits, p.figures) for k, p in ANCHOR.items()}
    bare_b = {k: RatePoint(*k, p.total_bits, p.figures) for k, p in TEST.items()}
    d = ctc_summary(SEQS, [COND], bare_a, bare_b)["conditions"][0]
    s = d["sequences"][0]
    assert s["bd_geometry_rate"]["GridD1"] is None and s["bd_rate"]["GridD1"] is not None  # total bits then
    assert s["component_ratios"]["texture"] is None and d["overall"]["time_ratios"]["encoder"] is None
    flat = {k: replace(p, figures={**p.figures, "IbsmLuma": 99.99}) for k, p in ANCHOR.items()}
    d = ctc_summary(SEQS, [COND], flat, TEST)["conditions"][0]  # an untextured anchor: IBSM luma 99.99 everywhere
    assert d["sequences"][0]["bd_rate"]["IbsmLuma"] is None and d["overall"]["bd_rate"]["IbsmLuma"] is None
    assert d["sequences"][0]["bd_rate"]["GridD1"] == pytest.approx(_bd("L", "GridD1", 1), abs=1e-6)


def test_reports_and_csv_round_trip(tmp_path: Path) -> None:
    """The test model's CSV: its header, mmetric's 9 digits, -1 and 0 as unknown; summary CSV and Markdown rows."""
    text = format_test_model_csv(ANCHOR.values())
    rows = list(csv.reader(io.StringIO(text)))
    assert tuple(rows[0]) == TEST_MODEL_COLUMNS and len(rows) == 10
    p = tmp_path / "anchor.csv"
    p.write_text(text)
    back = read_test_model_csv(p)
    for k, v in ANCHOR.items():
        assert back[k].total_bits == v.total_bits
        for m in METRICS:
            assert abs(back[k].figures[m] - v.figures[m]) <= 5e-9 * abs(v.figures[m])  # 9 significant digits
    p.write_text(text.replace("\n1,1,1,1000,", "\n1,1,1,-1,", 1))
    assert read_test_model_csv(p)[1, 1, 1].output_faces is None
    p.write_text(text + text.splitlines()[1] + "\n")
    with pytest.raises(ValueError, match=r"anchor.csv:11: SeqId 1, CondId 1, RateId 1 repeats"):
        read_test_model_csv(p)
    p.write_text(text.replace("\n1,1,1,1000,", "\n1,x,1,1000,", 1))
    with pytest.raises(ValueError, match=r"anchor.csv:2: column 'CondId': expected a number, found 'x'"):
        read_test_model_csv(p)
    # 0 bits gave the sequence no BD figure without a word (bd_rate's log of 0 was read as "not computable")
    row = text.splitlines()[1].split(",")
    row[4] = "0"
    p.write_text(text.replace(text.splitlines()[1], ",".join(row), 1))
    with pytest.raises(ValueError, match=r"anchor.csv:2: column 'TotalBitstreamBits': a coded point has bits, found 0"):
        read_test_model_csv(p)
    summary = ctc_summary(SEQS, [COND], ANCHOR, TEST)
    lines = summary_csv(summary).splitlines()
    assert [r.split(",")[1:3] for r in lines[1:]] == [
        ["sequence", "longdress"],
        ["sequence", "soldier"],
        ["sequence", "mitch"],
        ["class", "cat1-A"],
        ["class", "cat1-B"],
        ["overall", "overall"],
    ]
    md = summary_markdown(summary)
    assert "### BD-TotGeoRate [%]" in md and "| **cat1-A average** |" in md and "| **Overall average** |" in md


def test_an_average_over_a_cell_not_computable_is_not_computable() -> None:
    """The sheet's AVERAGE over a range holding an error is an error: a class or overall BD figure, a component or a
    time ratio whose cells are not all computable is None, and the scope names the cells lacking (review B #1, #3).
    Before, the mean of the computable cells alone was shown (the sphere's BD-rate as the overall average, the
    rate-2 metadata ratio for a sequence whose rate-1 ratio is #DIV/0!, a time ratio over the rows with runtimes)."""
    flat = {  # mitch's D1 curve at 99.99 for both codecs (identical decodes): its BD cell is the sheet's error
        k: replace(p, figures={**p.figures, "GridD1": 99.99}) if k[0] == 5 else p for k, p in ANCHOR.items()
    }
    flat_t = {k: replace(p, figures={**p.figures, "GridD1": 99.99}) if k[0] == 5 else p for k, p in TEST.items()}
    d = ctc_summary(SEQS, [COND], flat, flat_t)["conditions"][0]
    assert d["sequences"][2]["bd_rate"]["GridD1"] is None
    cls = {c["class"]: c for c in d["classes"]}
    assert abs(cls["cat1-A"]["bd_rate"]["GridD1"] - (_bd("L", "GridD1", 1) + _bd("L", "GridD1", 2)) / 2) < 1e-6
    assert cls["cat1-B"]["bd_rate"]["GridD1"] is None and cls["cat1-B"]["not_computable"] == {}  # its only cell
    assert d["overall"]["bd_rate"]["GridD1"] is None  # was the mean of longdress and soldier, -9.9 %
    assert d["overall"]["not_computable"] == {"bd_rate:GridD1": ["mitch"], "bd_geometry_rate:GridD1": ["mitch"]}
    assert abs(d["overall"]["bd_rate"]["GridD2"] - sum(_bd("L", "GridD2", s) for s in (1, 2, 5)) / 3) < 1e-6
    md = summary_markdown(ctc_summary(SEQS, [COND], flat, flat_t))
    assert "| **Overall average** | · |" in md
    assert "- **Overall average**, `bd_rate:GridD1`: not computable for mitch" in md

    # longdress: anchor metadata 0 at rate 1 (test 1000: #DIV/0!); test runtimes unknown at rate 2
    a2 = dict(ANCHOR)
    a2[1, 1, 1] = replace(ANCHOR[1, 1, 1], components={**ANCHOR[1, 1, 1].components, "metadata": 0.0})
    t2 = dict(TEST)
    t2[1, 1, 2] = replace(TEST[1, 1, 2], encoder_seconds=None, decoder_seconds=None)
    d = ctc_summary(SEQS, [COND], a2, t2)["conditions"][0]
    s = d["sequences"][0]
    assert s["rates"][0]["component_ratios"]["metadata"] is None and s["rates"][1]["component_ratios"]["metadata"] == 0
    assert s["component_ratios"]["metadata"] is None  # was rates 2-3's mean, 0 (+0.00 %)
    assert s["time_ratios"]["encoder"] is None and s["time_ratios"]["decoder"] is None  # was rates 1 and 3 only
    assert s["not_computable"] == {
        "component_ratios:metadata": ["longdress rate 1"],
        "time_ratios:encoder": ["longdress rate 2"],
        "time_ratios:decoder": ["longdress rate 2"],
    }
    assert _close(s["memory_ratios"]["encoder"], 0.9)  # every row known: computed
    assert d["overall"]["time_ratios"]["encoder"] is None and d["overall"]["component_ratios"]["metadata"] is None
    other = d["sequences"][1]  # soldier keeps its figures: SUM(B) / SUM(A) over its three rows
    enc = [(TEST[2, 1, r].encoder_seconds, ANCHOR[2, 1, r].encoder_seconds) for r in (1, 2, 3)]
    assert _close(other["time_ratios"]["encoder"], sum(b for b, _ in enc) / sum(a for _, a in enc))  # type: ignore[misc]
    md = summary_markdown(ctc_summary(SEQS, [COND], a2, t2))
    assert "- longdress, `time_ratios:encoder`: not computable for longdress rate 2" in md


def test_a_row_with_too_few_or_too_many_fields_is_refused(tmp_path: Path) -> None:
    """A row cut mid-write (an interrupted collect_results.sh) read its missing fields as unknown and a number cut
    mid-digits as is (review B #2): every row's field count is checked against the header's, naming file:line."""
    text = format_test_model_csv(ANCHOR.values())
    p = tmp_path / "anchor.csv"
    last = text.splitlines()[-1]
    p.write_text(text[: text.index(last)] + ",".join(last.split(",")[:5])[:-2] + "\n")  # "5,1,3,3000,57" cut
    with pytest.raises(ValueError, match=r"anchor.csv:10: expected 16 fields \(the header's\), found 5$"):
        read_test_model_csv(p)
    p.write_text(text.replace(last, last.rsplit(",", 1)[0]))  # no PeakDecoderMemory
    with pytest.raises(ValueError, match=r"anchor.csv:10: expected 16 fields \(the header's\), found 15$"):
        read_test_model_csv(p)
    p.write_text(text.replace(last, last + ",7"))
    with pytest.raises(ValueError, match=r"anchor.csv:10: expected 16 fields \(the header's\), found 17$"):
        read_test_model_csv(p)
    p.write_text(text + "\n")  # a blank line at the end is no row
    assert len(read_test_model_csv(p)) == 9


def test_a_header_with_a_trailing_space_is_read(tmp_path: Path) -> None:
    # The test model's collect_results.sh writes its newer header as "...,PeakDecoderMemory ,...": the column was
    # never read, so the decoder memory was unknown on every row (found by review, 2026-12-07).
    text = format_test_model_csv([RatePoint(1, 1, 2, 8000, {"GridD1": 70.5}, decoder_memory=512.0)])
    header, *rows = text.splitlines()
    assert "PeakDecoderMemory" in header.split(",")
    path = tmp_path / "a.csv"
    path.write_text("\n".join([header.replace("PeakDecoderMemory", "PeakDecoderMemory "), *rows]) + "\n")
    assert read_test_model_csv(path)[1, 1, 2].decoder_memory == 512.0


def test_the_markdown_summary_carries_the_lossless_mesh_ratio() -> None:
    # Review R #11: summary.csv and .json had a lossless condition's mesh_ratio (docs/ctc.md: the mesh-bits ratio
    # B / A - 1), summary.md and stdout had no such column.
    from torchmeshmetric.mpeg.ctc.sheet import summary_markdown

    a = {(1, 0, 0): RatePoint(1, 0, 0, 1000.0, components={"mesh_intra": 600.0, "mesh_inter": 100.0})}
    b = {(1, 0, 0): RatePoint(1, 0, 0, 800.0, components={"mesh_intra": 500.0, "mesh_inter": 60.0})}
    text = summary_markdown(ctc_summary(SEQS[:1], [SheetCondition(0, "C0 lossless AI", True)], a, b))
    header = next(line for line in text.splitlines() if "bpif ratio" in line)
    assert "| mesh ratio |" in header
    row = next(line for line in text.splitlines() if line.startswith(f"| {SEQS[0].name} |"))
    assert f"| {(560.0 / 700.0 - 1) * 100:+.2f} % |" in row  # -20.00 %
    lossy = summary_markdown(ctc_summary(SEQS, [COND], ANCHOR, TEST))
    assert "mesh ratio" not in lossy
