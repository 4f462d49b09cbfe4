"""``torchmeshmetric sample MESH OUT.ply``: the PLY body mm writes (where mm is present), and never an overwrite."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.cli import main

TESTS = MM_TESTS


def _body(path: Path) -> list[str]:
    lines = path.read_text().splitlines()
    return [line.rstrip() for line in lines[lines.index("end_header") + 1 :]]


@pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
@pytest.mark.parametrize(
    "name,texture,extra", [("plane_irregular", "plane_10_10.png", ["--bilinear"]), ("triangles", None, [])]
)
def test_same_body_as_mm(name: str, texture: str | None, extra: list[str], tmp_path: Path) -> None:
    obj, ours, theirs = TESTS / f"{name}.obj", tmp_path / "ours.ply", tmp_path / "mm.ply"
    tex = ["--texture", str(TESTS / texture)] if texture else []
    assert main(["sample", str(obj), str(ours), "--resolution", "16", *tex, *extra]) == 0
    args = [str(MM), "sample", "--mode", "face", "--resolution", "16", "-i", str(obj), "-o", str(theirs)]
    args += ["--hideProgress", "-m", str(TESTS / texture) if texture else "", *extra]
    subprocess.run(args, capture_output=True, timeout=120, check=True)
    assert _body(ours) == _body(theirs)


def test_refuses_to_overwrite(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    obj = tmp_path / "t.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    out = tmp_path / "out.ply"
    out.write_text("mine")
    assert main(["sample", str(obj), str(out), "--resolution", "4"]) == 1
    assert "already exists" in capsys.readouterr().err and out.read_text() == "mine"
    assert main(["sample", str(obj), str(out), "--resolution", "4", "--overwrite"]) == 0
    # step 1/4; edge 2-3 is sqrt(2) long: 1 + 2 + 3 + 5 + 6 points (mm sample prints "Generated 17 points")
    assert _body(out)[0] == "0 0 0 0 0 1" and len(_body(out)) == 17


def test_the_cloud_is_written_as_its_name_says(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # PLY text went to "out.obj" as well, a file no OBJ reader reads (found by review); out.obj is now an OBJ
    # (mm sample -o X.obj's), and other names are refused
    obj = tmp_path / "t.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert main(["sample", str(obj), str(tmp_path / "out.xyz"), "--resolution", "4"]) == 1
    assert f"OUT: {str(tmp_path / 'out.xyz')!r} must end with .ply or .obj" in capsys.readouterr().err
    assert not (tmp_path / "out.xyz").exists()
    assert main(["sample", str(obj), str(tmp_path / "out.PLY"), "--resolution", "4"]) == 0
    assert main(["sample", str(obj), str(tmp_path / "out.obj"), "--resolution", "4"]) == 0
    assert (tmp_path / "out.obj").read_text().splitlines()[:2] == ["", "v 0 0 0"]


@pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
def test_sdiv_same_rows_as_mm(tmp_path: Path) -> None:
    obj, ours, theirs = TESTS / "sphere.obj", tmp_path / "ours.ply", tmp_path / "mm.ply"
    assert main(["sample", str(obj), str(ours), "--mode", "sdiv", "--area-threshold", "0.01"]) == 0
    args = [str(MM), "sample", "--mode", "sdiv", "--areaThreshold", "0.01", "-i", str(obj), "-o", str(theirs)]
    subprocess.run([*args, "--hideProgress", "-m", ""], capture_output=True, timeout=120, check=True)
    assert sorted(_body(ours)) == sorted(_body(theirs))  # mm recurses depth first: another order


@pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
def test_ediv_same_rows_as_mm(tmp_path: Path) -> None:
    obj, ours, theirs = TESTS / "sphere.obj", tmp_path / "ours.ply", tmp_path / "mm.ply"
    assert main(["sample", str(obj), str(ours), "--mode", "ediv", "--resolution", "40"]) == 0
    args = [str(MM), "sample", "--mode", "ediv", "--resolution", "40", "-i", str(obj), "-o", str(theirs)]
    subprocess.run([*args, "--hideProgress", "-m", ""], capture_output=True, timeout=120, check=True)
    assert sorted(_body(ours)) == sorted(_body(theirs))  # mm recurses depth first: another order


@pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
def test_prnd_same_body_as_mm(tmp_path: Path) -> None:
    obj, ours, theirs = TESTS / "plane_irregular.obj", tmp_path / "ours.ply", tmp_path / "mm.ply"
    tex = str(TESTS / "plane_10_10.png")
    assert main(["sample", str(obj), str(ours), "--mode", "prnd", "--num-samples", "3000", "--texture", tex]) == 0
    args = [str(MM), "sample", "--mode", "prnd", "--nbSamples", "3000", "-i", str(obj), "-o", str(theirs)]
    subprocess.run([*args, "--hideProgress", "-m", tex], capture_output=True, timeout=120, check=True)
    assert _body(ours) == _body(theirs)


@pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
def test_map_same_body_as_mm(tmp_path: Path) -> None:
    obj, ours, theirs = TESTS / "plane_irregular.obj", tmp_path / "ours.ply", tmp_path / "mm.ply"
    tex = str(TESTS / "plane_16_16.png")
    assert main(["sample", str(obj), str(ours), "--mode", "map", "--texture", tex]) == 0
    args = [str(MM), "sample", "--mode", "map", "-i", str(obj), "-o", str(theirs), "--hideProgress", "-m", tex]
    subprocess.run(args, capture_output=True, timeout=120, check=True)
    assert _body(ours) == _body(theirs)


def test_errors_name_the_commands_arguments(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # The library's argument names (path, mesh, texture) were printed for the command's (found by review).
    obj = tmp_path / "t.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
    out = str(tmp_path / "o.ply")
    for argv, message in [
        ([str(bad), out], f"error: MESH: {str(bad)!r} line 4: face 0: vertex index 4 is out of range"),
        ([str(obj), out, "--mode", "map"], f"error: MESH {str(obj)!r}: map sampling needs UVs and a texture"),
        ([str(obj), out, "--texture", str(tmp_path / "no.png")], "error: --texture: texture file "),
    ]:
        assert main(["sample", *argv]) == 1
        assert message in capsys.readouterr().err
    assert not (tmp_path / "o.ply").exists()
