"""``torchmeshmetric sample --output-csv`` against the rows ``mm sample --outputCsv`` appended.

The stored CSVs (``tests/data/mmetric/outputs/sample_*.csv``) were written by ``mm`` v1.1.7, run in
``tests/data/mmetric`` on the relative names these tests give (the model column is the name as given, the texture
column ``./plane.png`` for a map found through ``plane.obj``'s MTL); the same runs against the binary itself, appended
twice, are at the end (skipped where ``mm`` is absent).
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg.comparison.csv_rows import SAMPLE_CSV_HEADERS, sample_csv_row

RUNS = {
    "face": [
        ["plane.obj", "--resolution", "64"],
        ["sphere.obj", "--resolution", "32", "--thickness", "0.3", "--bilinear", "--texture", "plane_16_16.png"],
        ["sphere.obj", "--num-samples-min", "1000", "--num-samples-max", "2000"],
    ],
    "sdiv": [
        ["plane.obj", "--area-threshold", "0.5"],
        ["sphere.obj", "--num-samples-min", "3000", "--num-samples-max", "3100"],
    ],
    "ediv": [
        ["plane.obj", "--length-threshold", "0.7"],
        ["sphere.obj", "--num-samples-min", "1000", "--num-samples-max", "2000", "--max-iterations", "4"],
    ],
    "prnd": [["plane.obj", "--num-samples", "500", "--bilinear"]],
    "map": [["plane_qp8.obj", "--texture", "plane_10_10.png"]],
}
"""The stored files' runs, in the sample command's words (mm's: --resolution, --thickness, --areaThreshold, ...)."""

MM_NAMES = {
    "--texture": "--inputMap",
    "--area-threshold": "--areaThreshold",
    "--length-threshold": "--lengthThreshold",
    "--num-samples": "--nbSamples",
    "--num-samples-min": "--nbSamplesMin",
    "--num-samples-max": "--nbSamplesMax",
    "--max-iterations": "--maxIterations",
}


def _ours(tmp: Path, mode: str, csv: Path) -> None:
    for run in RUNS[mode]:
        args = ["sample", run[0], str(tmp / "o.ply"), "--mode", mode, *run[1:], "--output-csv", str(csv)]
        assert main([*args, "--overwrite"]) == 0


@pytest.mark.parametrize("mode", sorted(RUNS))
def test_rows_as_mm_wrote_them(
    tmp_path: Path, mode: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(MM_TESTS)
    _ours(tmp_path, mode, tmp_path / "s.csv")
    assert (tmp_path / "s.csv").read_bytes() == (MM_TESTS / "outputs" / f"sample_{mode}.csv").read_bytes()
    capsys.readouterr()


def test_refusals(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Another mode's header is refused before any work (OUT not written); the CSV may not be an input."""
    mesh, out, csv = MM_TESTS / "plane.obj", tmp_path / "o.ply", tmp_path / "s.csv"
    csv.write_text(SAMPLE_CSV_HEADERS["sdiv"] + "\n")
    assert main(["sample", str(mesh), str(out), "--output-csv", str(csv)]) == 1
    assert "not this mode's header" in capsys.readouterr().err and not out.exists()
    assert csv.read_text() == SAMPLE_CSV_HEADERS["sdiv"] + "\n"
    assert main(["sample", str(mesh), str(out), "--output-csv", str(mesh)]) == 1
    assert "MESH" in capsys.readouterr().err and not out.exists()
    with pytest.raises(ValueError, match="mode: expected one of"):
        sample_csv_row("grid", model="m.obj", texture="", points=1)


@pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
@pytest.mark.parametrize("mode", sorted(RUNS))
def test_rows_against_mm(
    tmp_path: Path, mode: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Both tools twice into their CSV (the header once, then the rows appended), absolute names this time."""
    monkeypatch.chdir(MM_TESTS)
    mm_csv = tmp_path / "mm.csv"
    for _ in range(2):
        for run in RUNS[mode]:
            opts = [MM_NAMES.get(a, a) for a in run[1:]]
            args = [str(MM), "sample", "--mode", mode, "-i", run[0], "-o", str(tmp_path / "m.ply"), *opts]
            subprocess.run([*args, "--outputCsv", str(mm_csv), "--hideProgress"], capture_output=True, check=True)
        _ours(tmp_path, mode, tmp_path / "ours.csv")
    assert (tmp_path / "ours.csv").read_bytes() == mm_csv.read_bytes()
    assert len(mm_csv.read_text().splitlines()) == 1 + 2 * len(RUNS[mode])
    capsys.readouterr()


def test_obj_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``OUT.obj``: the OBJ mm sample -o writes (it was refused: OUT had to end with .ply)."""
    out = tmp_path / "s.obj"
    assert main(["sample", str(MM_TESTS / "plane.obj"), str(out), "--mode", "sdiv", "--area-threshold", "0.5"]) == 0
    assert out.read_bytes() == (MM_TESTS / "outputs" / "sdiv_plane.obj").read_bytes()
    qp8 = tmp_path / "qp8.obj"  # UVs and no map: mm keeps the UVs (it wrote no vt row here)
    assert main(["sample", str(MM_TESTS / "plane_qp8.obj"), str(qp8), "--mode", "sdiv", "--area-threshold", "5"]) == 0
    assert qp8.read_bytes() == (MM_TESTS / "outputs" / "sdiv_plane_qp8.obj").read_bytes()
    assert main(["sample", str(MM_TESTS / "plane.obj"), str(tmp_path / "s.txt")]) == 1
    assert "must end with .ply or .obj" in capsys.readouterr().err


def test_coloured_uvs_without_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Vertex colours and UVs without a map: sdiv and prnd keep the colours beside the UVs, as mm writes them (they
    were dropped: ``v x y z`` without colour, a PLY without ``red green blue``); prnd's inner points are black in mm."""
    from tests.mpeg.test_comparison_models import CSEAM

    mesh = tmp_path / "cs.obj"
    mesh.write_text(CSEAM)
    assert main(["sample", str(mesh), str(tmp_path / "s.obj"), "--mode", "sdiv", "--area-threshold", "2"]) == 0
    assert (tmp_path / "s.obj").read_bytes() == (MM_TESTS / "outputs" / "sdiv_cseam.obj").read_bytes()
    assert main(["sample", str(mesh), str(tmp_path / "p.ply"), "--mode", "prnd", "--num-samples", "20"]) == 0
    assert (tmp_path / "p.ply").read_bytes() == (MM_TESTS / "outputs" / "prnd_cseam.ply").read_bytes()
    capsys.readouterr()


def test_map_obj_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--mode map OUT.obj`` is mm's file: a ``vt`` row per point (its texel centre) and a last ``usemtl
    material0000`` (both were missing: 207 lines against mm's 311)."""
    out = tmp_path / "m.obj"
    args = ["sample", str(MM_TESTS / "plane.obj"), str(out), "--mode", "map"]
    assert main([*args, "--texture", str(MM_TESTS / "plane_10_10.png")]) == 0
    assert out.read_bytes() == (MM_TESTS / "outputs" / "map_plane.obj").read_bytes()
    capsys.readouterr()


@pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
def test_obj_output_against_mm(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """face, sdiv and prnd clouds as OBJ, byte for byte; plane_qp8 (UVs, no map) keeps its UVs in sdiv and prnd
    clouds (``vt`` rows, ``usemtl material0000``), and a count search's last cloud too."""
    runs = [("face", ["--resolution", "32"], ["--resolution", "32"]),
            ("sdiv", ["--areaThreshold", "0.05"], ["--area-threshold", "0.05"]),
            ("prnd", ["--nbSamples", "300"], ["--num-samples", "300"]),
            ("sdiv", ["--nbSamplesMin", "100", "--nbSamplesMax", "200"],
             ["--num-samples-min", "100", "--num-samples-max", "200"])]  # fmt: skip
    for mode, mm, ours in runs:
        for name in ("plane", "sphere_qp8", "triangles", "plane_qp8"):
            args = [str(MM), "sample", "--mode", mode, *mm, "-i", str(MM_TESTS / f"{name}.obj")]
            subprocess.run([*args, "-o", str(tmp_path / "m.obj"), "--hideProgress"], capture_output=True, check=True)
            mine = ["sample", str(MM_TESTS / f"{name}.obj"), str(tmp_path / "o.obj"), "--mode", mode, *ours]
            assert main([*mine, "--overwrite"]) == 0
            assert (tmp_path / "o.obj").read_bytes() == (tmp_path / "m.obj").read_bytes(), (mode, name)
    capsys.readouterr()
