"""``evaluate`` / ``compare --mpeg``: per-frame MPEG figures in the JSON, Markdown, CSV and plot; CTC averaging."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
import trimesh

from tests.cli.cli_helpers import Counting, write_frames
from torchmeshmetric.cli import main
from torchmeshmetric.data import load_sequence
from torchmeshmetric.mpeg import mpeg_metrics
from torchmeshmetric.mpeg.comparison.sequence import mean_psnr, mpeg_sequence


@pytest.fixture
def known_registration(monkeypatch: pytest.MonkeyPatch) -> Counting:
    fn = Counting()
    monkeypatch.setattr("torchmeshmetric.evaluation.pipeline.default_register", fn)
    monkeypatch.setattr("torchmeshmetric.evaluation.default_register", fn)
    return fn


def test_mean_psnr_rule() -> None:
    assert mean_psnr([30.0, 40.0]) == (35.0, 0)
    assert mean_psnr([30.0, math.inf, 40.0]) == (35.0, 1)  # an identical frame never breaks the average
    assert mean_psnr([math.inf, math.inf]) == (math.inf, 2)


def test_sequence_average_is_mean_of_frame_psnr() -> None:
    a = trimesh.creation.icosphere(2)
    b, c = a.copy().apply_scale(1.01), a.copy().apply_scale(0.98)
    seq = mpeg_sequence([a, a, a], [b, c, a], sampling="mesh")
    per = [mpeg_metrics(a, d, sampling="mesh").symmetric.d1_psnr for d in (b, c)]
    avg = seq.average()
    assert avg["d1_psnr"] == pytest.approx(sum(per) / 2, rel=1e-12)
    assert avg["d1_psnr_inf_frames"] == 1.0
    assert [row["d1_psnr"] for row in seq.frame_rows()][:2] == per
    with pytest.raises(ValueError, match="as many frames"):
        mpeg_sequence([a], [a, a])


def test_evaluate_mpeg_reports(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, known_registration: Counting
) -> None:
    orig, simp = write_frames(tmp_path / "orig", 2), write_frames(tmp_path / "simp", 1)
    out = tmp_path / "report.json"
    argv = ["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(out)]
    assert main([*argv, "--mpeg", "--mpeg-sampling", "mesh"]) == 0
    stdout = capsys.readouterr().out
    assert "## MPEG D1/D2 (mmetric, mesh sampling)" in stdout
    report = json.loads(out.read_text())
    frames = report["mpeg"]["simp"]["frames"]
    expect = [
        mpeg_metrics(o, s, sampling="mesh").symmetric
        for o, s in zip(load_sequence(str(orig)), load_sequence(str(simp)), strict=True)
    ]
    assert [f["d1_psnr"] for f in frames] == [e.d1_psnr for e in expect]
    assert [f["d2_hausdorff"] for f in frames] == [e.d2_hausdorff for e in expect]
    assert report["mpeg"]["simp"]["average"]["d1_psnr"] == pytest.approx(sum(e.d1_psnr for e in expect) / 3)
    assert "mean over frames of the per-frame PSNR" in report["mpeg"]["simp"]["averaging"]
    md = out.with_suffix(".md").read_text()
    assert "Table I:" in md and "| simp | mean |" in md
    rows = list(csv.DictReader(out.with_suffix(".mpeg.csv").read_text().splitlines()))
    assert [r["frame"] for r in rows] == ["0", "1", "2", "mean"]
    assert float(rows[1]["d2_psnr"]) == expect[1].d2_psnr
    assert out.with_suffix(".mpeg.png").read_bytes()[:4] == b"\x89PNG"


def test_compare_mpeg_identical_frames_are_inf_strings(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, known_registration: Counting
) -> None:
    orig = write_frames(tmp_path / "orig", 1)
    same = write_frames(tmp_path / "same", 1)
    out = tmp_path / "r.json"
    argv = ["compare", "--original", str(orig), "--method", f"same={same}", "--out", str(out), "--mpeg"]
    assert main([*argv, "--mpeg-grid-size", "32"]) == 0
    capsys.readouterr()
    report = json.loads(out.read_text())  # strict JSON
    assert report["mpeg"]["same"]["average"]["d1_psnr"] == "inf"
    assert report["mpeg"]["same"]["average"]["d1_psnr_inf_frames"] == 3.0
    assert all(f["d2_psnr"] == "inf" for f in report["mpeg"]["same"]["frames"])


def test_metric_accumulates_ctc_average() -> None:
    from torchmeshmetric.mpeg import MpegPSNR

    a = trimesh.creation.icosphere(2)
    b, c = a.copy().apply_scale(1.01), a.copy().apply_scale(0.97)
    m = MpegPSNR(sampling="mesh")
    for d in (b, c, a):
        m.update(d, a)
    out = m.compute()
    per = [mpeg_metrics(a, d, sampling="mesh").symmetric for d in (b, c)]
    assert out["d1_psnr"].item() == pytest.approx(sum(p.d1_psnr for p in per) / 2, rel=1e-12)
    assert out["d2_psnr"].item() == pytest.approx(sum(p.d2_psnr for p in per) / 2, rel=1e-12)
    assert out["d1_psnr_inf_frames"].item() == 1.0
    m.reset()
    m.update(a, a)
    assert math.isinf(m.compute()["d2_psnr"].item())
    with pytest.raises(ValueError, match="grid_size"):
        MpegPSNR(grid_size=0)
