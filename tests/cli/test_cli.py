import json
import os
import subprocess
import sys

import pytest

from tests.cli.cli_helpers import Counting, write_frames
from torchmeshmetric.cli import build_parser, main
from torchmeshmetric.data import load_sequence
from torchmeshmetric.evaluation import SET_NAMES, evaluate_sequence


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_evaluate_writes_reports_equal_to_the_library(capsys, tmp_path, sequence, known_registration):
    orig, simp = sequence
    out = tmp_path / "report.json"
    code, stdout, stderr = _run(
        capsys, "evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(out)
    )
    assert code == 0, stderr
    assert "Table I:" in stdout and "Table IV:" in stdout
    assert "frame pair 2/2" in stderr  # progress per frame on stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["orig", "report.csv", "report.json", "report.md", "simp"]
    report = json.loads(out.read_text())
    expect = evaluate_sequence(load_sequence(str(orig)), load_sequence(str(simp)), registration_fn=Counting())
    got = report["methods"]["simp"]
    for pair, jpair in zip(expect.pairs, got["pairs"], strict=True):
        for s in SET_NAMES:
            for field in ("ave", "var", "std", "mse", "rmse", "max", "p95"):
                assert jpair[s][field] == getattr(pair.statistics[s], field)
    assert known_registration.calls == 2


def test_compare_registers_each_original_pair_once(capsys, tmp_path, sequence, known_registration):
    orig, simp = sequence
    other = write_frames(tmp_path / "other", 0)
    code, stdout, stderr = _run(
        capsys, "compare", "--original", str(orig), "--method", f"A={simp}", "--method", f"B={other}"
    )
    assert code == 0, stderr
    assert known_registration.calls == 2
    table1 = stdout.split("Table II")[0]
    assert "| A | (k-1)-th |" in table1 and "| B | k-th |" in table1


def test_compare_two_identical_method_folders_every_verdict_inconclusive(
    capsys, tmp_path, sequence, known_registration
):
    orig, simp = sequence
    out = tmp_path / "cmp.json"
    code, stdout, stderr = _run(
        capsys, "compare", "--original", str(orig), "--method", f"A={simp}", "--method", f"B={simp}", "--out", str(out)
    )
    assert code == 0, stderr
    comparisons = json.loads(out.read_text())["comparisons"]
    assert list(comparisons) == ["A vs B"]
    entries = [e for stats in comparisons["A vs B"].values() for e in stats.values()]
    assert len(entries) >= 10 * 4  # 5 sets + 5 reverse sets, ave/rmse/max/p95 (and psnr)
    assert all(e["verdict"] == "inconclusive" and e["difference"] == 0.0 for e in entries)
    assert "Comparisons with confidence" in stdout and "| flicker * |" in stdout
    assert "Comparisons with confidence" in out.with_suffix(".md").read_text()
    # Refused when parsed, naming the option: it was refused after the whole registration and evaluation (review).
    with pytest.raises(SystemExit) as exit_:
        main(["compare", "--original", str(orig), "--method", f"A={simp}", "--method", f"B={simp}",
              "--relative-margin", "-1"])  # fmt: skip
    assert exit_.value.code == 2
    assert "argument --relative-margin: expected a finite fraction >= 0, found '-1'" in capsys.readouterr().err


@pytest.mark.parametrize("out", [False, True])
@pytest.mark.parametrize("which", ["--original", "--simplified", "--method"])
def test_an_empty_frame_folder_is_named_by_its_option(capsys, tmp_path, sequence, which, out):
    # Found by review O: the outputs' check listed the input frames first, even without --out, and said
    # "paths: directory 'empty' holds no mesh files": "paths" is a parameter of list_frames, no option
    orig, simp = sequence
    empty = tmp_path / "empty"
    empty.mkdir()
    argv = {
        "--original": ["evaluate", "--original", str(empty), "--simplified", str(simp)],
        "--simplified": ["evaluate", "--original", str(orig), "--simplified", str(empty)],
        "--method": ["compare", "--original", str(orig), "--method", f"A={simp}", "--method", f"B={empty}"],
    }[which]
    report = tmp_path / "r.json"
    code, _, stderr = _run(capsys, *argv, *(["--out", str(report)] if out else []))
    option = "--method B" if which == "--method" else which
    expected = f"error: {option} {str(empty)!r}: directory {str(empty)!r} holds no mesh files (suffixes .obj"
    assert code == 1 and expected in stderr and "paths" not in stderr, stderr
    assert not report.exists()


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("missing", "no such directory"),
        ("file", "is a file; expected a folder of frames"),
        ("count", "--simplified"),  # named by the options since 2026-12-07 (it said "method 'simp'": no option)
        ("corrupt", "frame_01.ply"),
        ("unwritable", "does not exist"),
        ("exists", "already exists"),
    ],
)
def test_errors_are_one_line_no_traceback_no_report(capsys, tmp_path, sequence, known_registration, case, message):
    orig, simp = sequence
    out = tmp_path / "report.json"
    if case == "missing":
        simp = tmp_path / "nope"
    elif case == "file":
        simp = simp / "frame_01.ply"
    elif case == "count":
        (simp / "frame_02.ply").unlink()
    elif case == "corrupt":
        (simp / "frame_01.ply").write_bytes(b"ply\nformat nonsense\n\x00\x01")
    elif case == "unwritable":
        out = tmp_path / "no" / "such" / "report.json"
    elif case == "exists":
        out.write_text("keep me")
    code, _, stderr = _run(capsys, "evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(out))
    assert code == 1
    lines = [line for line in stderr.splitlines() if "frame pair" not in line]
    assert len(lines) == 1 and "error:" in lines[0] and message in lines[0], stderr
    if case == "count":
        assert lines[0].endswith(
            f"2 frames but --original {str(orig)!r} has 3 (must match; the original frames run from 0 to 2, these "
            "from 0 to 1): frame 2 of the original frames ('frame_02.ply') is missing here"
        )
    assert "Traceback" not in stderr
    if case == "exists":
        assert out.read_text() == "keep me"
    else:
        assert not out.exists() and not out.with_suffix(".md").exists() and not out.with_suffix(".csv").exists()
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


def test_bad_method_spec_and_cuda_without_gpu(capsys, tmp_path, sequence):
    orig, simp = sequence
    code, _, err = _run(capsys, "compare", "--original", str(orig), "--method", str(simp))
    assert code == 1 and "expected NAME=DIR" in err
    code, _, err = _run(capsys, "compare", "--original", str(orig), "--method", f" ={simp}")  # found by review E
    assert code == 1 and f"--method ' ={simp}': expected NAME=DIR" in err
    import torch

    if not torch.cuda.is_available():
        code, _, err = _run(capsys, "evaluate", "--original", str(orig), "--simplified", str(simp), "--device", "cuda")
        assert code == 1 and "no CUDA device" in err


def test_help_explains_every_option():
    parser = build_parser()
    subparsers = next(a for a in parser._actions if a.dest == "command").choices
    assert set(subparsers) == {
        "evaluate",
        "compare",
        "campaign",
        "simplify",
        "register",
        "demo",
        "mpeg",
        "sample",
        "ctc",
        "ctc-campaign",
        "ctc-face-errors",
        "bdrate",
        "build",
        "validate",
        "report",
        "temporal",
    }
    for name, sub in subparsers.items():
        for action in sub._actions:
            assert action.help, f"{name} {action.option_strings} has no help"


def test_python_dash_m_help():
    r = subprocess.run([sys.executable, "-m", "torchmeshmetric", "--help"], capture_output=True, text=True, check=False)
    assert r.returncode == 0 and "evaluate" in r.stdout and "demo" in r.stdout


def test_frame_counts_that_differ_name_the_frame_one_folder_lacks(capsys, tmp_path):
    """Numbered frames: the first number in one folder only, either way (review O: only the counts were named)."""
    orig = write_frames(tmp_path / "orig", 1, n=4)
    simp = write_frames(tmp_path / "simp", 1, n=5)
    (simp / "frame_01.ply").unlink()
    (simp / "frame_02.ply").unlink()  # 3 frames: 00, 03, 04
    code, _, stderr = _run(capsys, "evaluate", "--original", str(orig), "--simplified", str(simp))
    assert code == 1
    assert stderr.strip().endswith(
        f"--simplified {str(simp)!r}: 3 frames but --original {str(orig)!r} has 4 (must match; the original frames "
        "run from 0 to 3, these from 0 to 4): frame 1 of the original frames ('frame_01.ply') is missing here; 3 "
        "frame numbers are in one folder only"
    ), stderr
    code, _, stderr = _run(capsys, "evaluate", "--original", str(simp), "--simplified", str(orig))
    assert code == 1
    assert stderr.strip().endswith(
        f"--simplified {str(orig)!r}: 4 frames but --original {str(simp)!r} has 3 (must match; the original frames "
        "run from 0 to 4, these from 0 to 3): frame 1 ('frame_01.ply') has no original frame; 3 frame numbers are in "
        "one folder only"
    ), stderr
