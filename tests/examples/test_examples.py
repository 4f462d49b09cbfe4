"""Every example in examples/ runs as its docstring says, and prints or writes what it should.

Each example is run in this process (``runpy``, ``__name__ == "__main__"``, its own ``sys.argv``), as
``PYTHONPATH=. python examples/<name>.py ...`` runs it, and its output is checked: values against an independent
computation where one is cheap (scipy's cKDTree for nearest vertex distances), otherwise against what the example
itself writes, and the behaviour it demonstrates (a loss that falls, a learned shift that undoes the data's).
``train_temporal_simplifier.py`` has its own test (test_train_temporal_simplifier.py). Sizes: the examples' own
defaults, except ``make_campaign_data.py`` (2 frames at resolution 16, through its arguments).
"""

from __future__ import annotations

import ast
import contextlib
import io
import itertools
import json
import math
import re
import runpy
import shutil
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from torchmeshmetric._format import format_number
from torchmeshmetric.evaluation.reports import COLUMN_FORMATS

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def run_example(name: str, *argv: object) -> str:
    """Run ``examples/<name>`` as a script with ``argv``; its standard output. A ``SystemExit`` must be 0."""
    path = EXAMPLES / name
    out = io.StringIO()
    saved = sys.argv
    sys.argv = [str(path), *map(str, argv)]
    try:
        with contextlib.redirect_stdout(out):
            runpy.run_path(str(path), run_name="__main__")
    except SystemExit as e:
        assert e.code in (0, None), f"{name} exited with {e.code}"
    finally:
        sys.argv = saved
    return out.getvalue()


@pytest.fixture(autouse=True, scope="module")
def one_thread() -> Iterator[None]:
    """Many small ops: on a shared machine each parallel region would wait for a busy core."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_train_with_loss_lowers_the_loss_and_prints_the_final_statistics() -> None:
    out = run_example("train_with_loss.py")
    steps = [(int(s), float(v)) for s, v in re.findall(r"step\s+(\d+)\s+loss (\S+)", out)]
    assert [s for s, _ in steps] == list(range(0, 61, 10))
    losses = [v for _, v in steps]
    assert all(b < a for a, b in itertools.pairwise(losses))  # Adam on the two-sided loss
    assert losses[-1] < 0.05 * losses[0]  # measured: 0.000997 against 0.065981
    final = ast.literal_eval(out.strip().splitlines()[-1])  # the printed dict of statistics
    assert final["hausdorff"] == max(final["max"], final["reverse_max"])
    assert final["ave"] <= final["rmse"] <= final["max"]
    # Measured here: ave 0.0169, rmse 0.02037, max 0.04814; float32 Adam through 61 steps moves them by < 6e-4
    # (relative) between ATEN_CPU_CAPABILITY=avx2 and =default, so other CPUs stay well within 1e-2.
    for key, value in {"ave": 0.0169, "rmse": 0.02037, "max": 0.04814}.items():
        assert final[key] == pytest.approx(value, rel=1e-2), key


def test_validation_metrics_prints_the_pooled_statistics_of_every_batch() -> None:
    from scipy.spatial import cKDTree

    out = run_example("validation_metrics.py")
    epochs = re.findall(r"epoch (\d): (.*)", out)
    assert [e for e, _ in epochs] == ["0", "1"]
    logged = [dict((k, float(v)) for k, v in re.findall(r"(\S+)=(\S+?)(?:,|$)", line)) for _, line in epochs]
    assert logged[0] == logged[1]  # reset between epochs, same batches: the same values
    # The nearest vertex statistics from scratch: every simplified vertex of every batch to its reference's vertices.
    module = runpy.run_path(str(EXAMPLES / "validation_metrics.py"))
    dists, peak = [], 0.0
    for simplified, reference in module["validation_batches"]():
        for (v, _), ref in zip(simplified, reference, strict=True):
            dists.append(cKDTree(ref.vertices).query(v.double().numpy())[0])
            peak = max(peak, float(np.linalg.norm(ref.vertices.max(0) - ref.vertices.min(0))))
    d = np.concatenate(dists)
    assert logged[0]["val/vertex_ave"] == pytest.approx(d.mean(), abs=5e-6)  # printed with 5 decimals
    assert logged[0]["val/vertex_psnr"] == pytest.approx(10 * math.log10(peak**2 / (d**2).mean()), abs=5e-6)
    # The surface distance is at most the nearest vertex distance, and its statistics are ordered.
    s = logged[0]
    assert 0 < s["val/surface_ave"] <= s["val/vertex_ave"]
    assert s["val/surface_ave"] <= s["val/surface_rmse"] <= s["val/surface_hausdorff"]


def test_validation_temporal_consistency_improves_every_epoch() -> None:
    out = run_example("validation_temporal_consistency.py")
    rows = re.findall(r"epoch (\d): surface_k_minus_1/rmse (\S+)\s+reverse/surface_k/max (\S+)", out)
    assert [r[0] for r in rows] == ["0", "1", "2"]
    rmse = [float(r[1]) for r in rows]
    reverse_max = [float(r[2]) for r in rows]
    # Training pulls the scaled templates onto the frames: both sets shrink (measured 0.1841, 0.1567, 0.1300).
    assert rmse[0] > rmse[1] > rmse[2] > 0 and reverse_max[0] > reverse_max[1] > reverse_max[2] > 0
    assert rmse[0] < 0.25  # the templates start 20 % larger than the unit frames: about 0.2 off


def test_lightning_validation_logs_every_epoch_and_learns_the_shift() -> None:
    pytest.importorskip("lightning")
    out = run_example("lightning_validation.py")
    rows = [dict(kv.split("=") for kv in line.split(", ")) for line in out.splitlines() if line.startswith("epoch=")]
    assert [r["epoch"] for r in rows] == ["0", "1", "2", "3"]
    ave = [float(r["val/surface_ave"]) for r in rows]
    assert all(b < a for a, b in itertools.pairwise(ave))
    for r in rows:  # the views of one metric: its Hausdorff bounds its average
        assert float(r["val/surface_ave"]) < float(r["val/surface_hausdorff"])
    shift = json.loads(re.search(r"learned shift: (\[.*?\])", out).group(1))  # type: ignore[union-attr]
    # The data's coarse meshes were moved by (+0.05, -0.03, 0): the model learns to undo it (measured
    # [-0.0461, 0.0266, 0.0004] after 4 epochs).
    assert np.allclose(shift, [-0.05, 0.03, 0.0], atol=0.01), shift


@pytest.fixture(scope="module")
def campaign_data(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``make_campaign_data.py`` run once (2 frames, resolution 16): the folder and what it printed."""
    root = tmp_path_factory.mktemp("campaign")
    out = run_example("make_campaign_data.py", root / "campaign-data", "--frames", 2, "--resolution", 16)
    return root, out


def _num_faces(path: Path) -> int:
    from torchmeshmetric.data import load_mesh

    return load_mesh(path).num_faces


def test_make_campaign_data_writes_the_campaign_folders(campaign_data: tuple[Path, str]) -> None:
    root, _ = campaign_data
    data = root / "campaign-data"
    for seed in ("seed0", "seed1"):
        names = {p.name for p in (data / seed / "original").iterdir()}
        assert names == {"frame_000.ply", "frame_001.ply"}
        for method, keep in (("qem90", 0.9), ("qem50", 0.5)):
            assert {p.name for p in (data / seed / method).iterdir()} == names
            for name in names:
                original = _num_faces(data / seed / "original" / name)
                simplified = _num_faces(data / seed / method / name)
                assert abs(simplified - keep * original) <= 2  # QEM to the target, within a collapse (two faces)


@pytest.fixture(scope="module")
def folder_report(campaign_data: tuple[Path, str]) -> tuple[str, dict[str, Any]]:
    """``evaluate_folder.py`` on seed0's original and qem50 frames: what it printed and the JSON it wrote."""
    root, _ = campaign_data
    data = root / "campaign-data" / "seed0"
    report = root / "qem50.json"
    out = run_example("evaluate_folder.py", data / "original", data / "qem50", "--out", report)
    return out, json.loads(report.read_text())


def test_evaluate_folder_prints_the_tables_and_writes_the_report(folder_report: tuple[str, dict[str, Any]]) -> None:
    out, report = folder_report
    method = report["methods"]["qem50"]
    pair = method["pairs"][0]
    assert pair["frame"] == 1 and len(method["pairs"]) == 1
    # The per-frame line and the table rows print what the JSON holds, to the tables' digits (COLUMN_FORMATS): those of
    # the per-frame figures, which go through the registration, are those of frame k's Ave, which does not.
    line = re.search(r"frame 1: surface_k_minus_1 rmse (\S+), registration residual rmse (\S+)", out)
    assert line is not None
    assert line.group(1) == format_number(pair["surface_k_minus_1"]["rmse"], COLUMN_FORMATS["rmse"])
    assert line.group(2) == format_number(pair["registration"]["residual"]["rmse"], COLUMN_FORMATS["rmse"])
    row = re.search(r"\| qem50 \| k-th \| (\S+) \|", out)
    printed = format_number(method["aggregate"]["surface_k"]["ave"], COLUMN_FORMATS["ave"])  # the report's digits
    assert row is not None and row.group(1) == printed
    # the note names the file it wrote, not a report.json it never writes (found by review E)
    assert "qem50.json keeps the full values" in out and "report.json" not in out


def test_evaluate_folder_refuses_an_existing_out_before_evaluating(campaign_data, capsys, monkeypatch) -> None:
    # A second run with the same --out died with a FileExistsError traceback after the whole evaluation (review E)
    root, _ = campaign_data
    data = root / "campaign-data" / "seed0"
    out = root / "exists.json"
    out.write_text("keep me")
    monkeypatch.setattr("torchmeshmetric.evaluation.evaluate_sequence", _never_called)
    monkeypatch.setattr(
        sys, "argv", ["evaluate_folder.py", str(data / "original"), str(data / "qem50"), "--out", str(out)]
    )
    with pytest.raises(SystemExit) as info:
        runpy.run_path(str(EXAMPLES / "evaluate_folder.py"), run_name="__main__")
    assert info.value.code == 2 and "already exists (pass --overwrite" in capsys.readouterr().err
    assert out.read_text() == "keep me"


def _never_called(*args: object, **kwargs: object) -> None:
    raise AssertionError("evaluated before --out was checked")


def test_campaign_toml_runs_and_agrees_with_evaluate_folder(
    campaign_data: tuple[Path, str], folder_report: tuple[str, dict[str, Any]], tmp_path: Path
) -> None:
    """``torchmeshmetric campaign examples/campaign.toml`` (copied beside the data it names)."""
    from torchmeshmetric.cli import main as cli

    root, _ = campaign_data
    shutil.copy(EXAMPLES / "campaign.toml", root / "campaign.toml")
    with contextlib.redirect_stdout(io.StringIO()):
        assert cli(["campaign", str(root / "campaign.toml"), "--out-dir", str(tmp_path / "report")]) == 0
    written = {p.name for p in (tmp_path / "report").iterdir()}
    for stem in ("campaign", "performer-seed0", "performer-seed1"):
        assert {f"{stem}.json", f"{stem}.md", f"{stem}.csv"} <= written
    campaign = json.loads((tmp_path / "report" / "campaign.json").read_text())
    assert campaign["settings"]["registration"] == "fast" and campaign["settings"]["two_sided"] is True
    sequences = campaign["sequences"]
    assert set(sequences) == {"performer-seed0", "performer-seed1"}
    assert all(set(s["methods"]) == {"QEM 90%", "QEM 50%"} for s in sequences.values())
    # surface_k (simplified frame k against original frame k) does not depend on the registration: the campaign's
    # "fast" one and evaluate_folder's default one give the same statistics for the same frames.
    _, report = folder_report
    got = sequences["performer-seed0"]["methods"]["QEM 50%"]["aggregate"]["surface_k"]
    expected = report["methods"]["qem50"]["aggregate"]["surface_k"]
    assert got["ave"] == pytest.approx(expected["ave"], rel=1e-12) and got["max"] == expected["max"]


def _exit_code(name: str, *argv: object) -> int:
    """Run ``examples/<name>`` with ``argv``, which must end in ``SystemExit``; its code."""
    with pytest.raises(SystemExit) as info:
        sys.argv = [str(EXAMPLES / name), *map(str, argv)]
        runpy.run_path(str(EXAMPLES / name), run_name="__main__")
    return int(info.value.code or 0)


@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_make_ctc_campaign_data_help_prints_the_usage_and_writes_nothing(flag, tmp_path, monkeypatch, capsys):
    # Review I #10: the flag was taken for the output folder: the whole data set went into a folder named --help.
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", sys.argv)  # restored after _exit_code sets it
    assert _exit_code("make_ctc_campaign_data.py", flag) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: make_ctc_campaign_data.py [-h] OUTPUT_FOLDER") and "ctc_campaign.toml" in out
    assert list(tmp_path.iterdir()) == []


def test_make_ctc_campaign_data_names_a_manifest_that_reads_its_folder(tmp_path, monkeypatch):
    # Review I #10: the hint named examples/ctc_campaign.toml whatever folder was written, and that manifest reads
    # examples/ctc-campaign-data only. The manifest written beside the data reads the data, wherever it is.
    from torchmeshmetric.mpeg.ctc.campaign import plan_frames
    from torchmeshmetric.mpeg.ctc.manifest import load_ctc_campaign

    monkeypatch.setattr(sys, "argv", sys.argv)
    out = run_example("make_ctc_campaign_data.py", tmp_path / "elsewhere")
    manifest = tmp_path / "elsewhere" / "ctc_campaign.toml"
    assert out.strip() == (
        f"wrote {tmp_path / 'elsewhere'}; run: torchmeshmetric ctc-campaign {manifest} --out-dir ctc-report"
    )
    campaign = load_ctc_campaign(manifest)
    assert campaign.cache_dir == tmp_path / "elsewhere" / "cache"
    tasks = plan_frames(campaign)  # every frame file found (plan_frames checks each)
    assert len(tasks) == 2 * 2 * 2 * 5  # codecs x sequences x rates x frames
    assert {Path(t.ref).parent for t in tasks} == {tmp_path / "elsewhere" / s / "src" for s in ("sphere", "ellipsoid")}


@pytest.mark.parametrize(("option", "value"), [("--frames", 0), ("--frames", 1), ("--resolution", 8)])
def test_make_campaign_data_refuses_bad_sizes_before_making_a_folder(option, value, tmp_path, monkeypatch, capsys):
    # Review I #10: --frames 0 made out/seed0/ and died with demo_sequence's traceback.
    monkeypatch.setattr(sys, "argv", sys.argv)
    assert _exit_code("make_campaign_data.py", tmp_path / "out", option, value) == 2
    low = 16 if option == "--resolution" else 2
    assert f"argument {option}: expected an int >= {low}, found {value}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_campaign_with_a_read_only_cache_folder_warns_and_writes_its_reports(
    campaign_data: tuple[Path, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    # Review I #6: `campaign --cache-dir` on a read-only folder died at the first registration it computed, after its
    # work, naming a temporary file ("[Errno 30] Read-only file system: '.../.a49c...pt.6592.tmp'"), and wrote no
    # report. It now warns once, naming the folder, and writes the reports a writable cache gives.
    import errno

    from torchmeshmetric.cli import main as cli

    root, _ = campaign_data
    shutil.copy(EXAMPLES / "campaign.toml", root / "campaign.toml")
    with contextlib.redirect_stdout(io.StringIO()):
        assert cli(["campaign", str(root / "campaign.toml"), "--out-dir", str(tmp_path / "writable"),
                    "--cache-dir", str(tmp_path / "cache")]) == 0  # fmt: skip

    def read_only(path: Path, *args: object, **kwargs: object) -> None:
        raise OSError(errno.EROFS, "Read-only file system", str(path.parent / f".{path.name}.1234.tmp"))

    monkeypatch.setattr("torchmeshmetric.registration.cache.atomic_write_with", read_only)
    capsys.readouterr()
    with pytest.warns(UserWarning) as record, contextlib.redirect_stdout(io.StringIO()):
        code = cli(["campaign", str(root / "campaign.toml"), "--out-dir", str(tmp_path / "read-only"),
                    "--cache-dir", str(tmp_path / "archive")])  # fmt: skip
    assert code == 0
    stored = [str(w.message) for w in record if "registration cache" in str(w.message)]
    assert stored == [
        f"registration cache: cannot store entries in {tmp_path / 'archive'} (Read-only file system); this run "
        "keeps its registrations in memory only (the entries already there are still read)"
    ]
    got = json.loads((tmp_path / "read-only" / "campaign.json").read_text())["sequences"]
    want = json.loads((tmp_path / "writable" / "campaign.json").read_text())["sequences"]
    for name, sequence in want.items():
        for method, figures in sequence["methods"].items():
            assert got[name]["methods"][method]["aggregate"] == figures["aggregate"], (name, method)
