"""Bad input to ctc, bdrate and the mpeg library: one typed error naming the option (or file:line), before any work,
and no output left behind (issue 29's cases)."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from tests.mpeg.test_cli_ctc import _sequence
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.mpeg.ctc.bd_rate import bd_rate
from torchmeshmetric.mpeg.ctc.chain import ctc_frame, ctc_mean
from torchmeshmetric.structures import Mesh


def _with(args: list[str], option: str, value: str) -> list[str]:
    i = args.index(option)
    return [*args[: i + 1], value, *args[i + 2 :]]


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("--ibsm-resolution", "0", "--ibsm-resolution: expected an integer in 1.."),
        ("--ibsm-cameras", "1", "--ibsm-cameras: expected an integer in 2.."),
        ("--grid-size", "0", "--grid-size: expected an integer in 1.."),
        ("--qp", "3", "--qp: expected an integer in 7..31"),
        ("--qt", "40", "--qt: expected an integer in 0..31"),
        ("--resolution", "nan", "--resolution: expected a positive number"),
        # review X F4: found per frame under the library's name (peak: ... (while running frame 0)), and 1e39 as
        # "max_pos: expected 3 finite numbers" after numpy's overflow warning
        ("--resolution", "1e-300", "error: --resolution: expected a positive number within float32's range"),
        ("--max-pos", "1e39 1 1", "error: --max-pos: [1e+39, 1.0, 1.0] is beyond float32's range (mmetric reads"),
    ],
)
def test_ctc_options_checked_by_name_first(tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str,
                                           value: str, message: str) -> None:  # fmt: skip
    assert main(_with(_sequence(tmp_path), option, value)) == 1
    err = capsys.readouterr().err
    assert message in err and "ctc: frame" not in err and "Warning" not in err


def test_ctc_decoded_qt_checked_without_uvs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*_sequence(tmp_path), "--decoded-qt", "99"]) == 1
    assert "--decoded-qt: expected an integer in 0..31, found 99" in capsys.readouterr().err


def test_ctc_out_folder_checked_first(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = [*_sequence(tmp_path), "--no-ibsm"]
    assert main([*args, "--out", str(tmp_path / "missing" / "r")]) == 1
    err = capsys.readouterr().err
    assert "does not exist" in err and "missing" in err and "ctc: frame" not in err
    if os.geteuid() != 0:  # root writes anywhere
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        assert main([*args, "--out", str(ro / "r")]) == 1
        assert "not writable" in capsys.readouterr().err
        assert list(ro.iterdir()) == []


def test_ctc_empty_or_directory_frame_checked_first(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = _sequence(tmp_path, 3)
    (tmp_path / "dec_002.obj").write_text("")
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "--decoded: frame 2: file" in err and "is empty" in err and "ctc: frame" not in err
    (tmp_path / "dec_002.obj").unlink()
    (tmp_path / "dec_002.obj").mkdir()
    assert main(args) == 1
    assert "is a directory, expected a file" in capsys.readouterr().err


def test_ctc_decoded_texture_needs_uvs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from PIL import Image

    Image.new("RGB", (4, 4), (200, 10, 10)).save(tmp_path / "dec_000.png")
    Image.new("RGB", (4, 4), (200, 10, 10)).save(tmp_path / "dec_001.png")
    args = [*_sequence(tmp_path), "--no-ibsm", "--decoded-texture", str(tmp_path / "dec_%03d.png")]
    assert main(args) == 1
    assert "--decoded-texture: frame 0: the decoded OBJ has no texture coordinates" in capsys.readouterr().err


def test_ctc_frame_losing_colour_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Frame 1 without the colours frame 0 has: the colour means would silently skip it."""
    args = [*_sequence(tmp_path), "--no-ibsm"]
    for name in ("src", "dec"):
        p = tmp_path / f"{name}_000.obj"
        p.write_text("\n".join(ln + " 0.5 0.5 0.5" if ln.startswith("v ") else ln for ln in p.read_text().split("\n")))
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "frame 1: the reference frame has no colour" in err


def test_ctc_frame_resolution_checked() -> None:
    q = TexturedMesh(Mesh(torch.tensor([[0.0, 0, 0], [9, 0, 0], [0, 9, 0]]), torch.tensor([[0, 1, 2]])))
    kw = dict(qp=10, qt=0, min_pos=[0, 0, 0], max_pos=[1, 1, 1], grid_size=16, ibsm_resolution=None)
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="resolution: expected a positive finite"):
            ctc_frame(q, q, resolution=bad, **kw)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="resolution: expected a real number"):
        ctc_frame(q, q, resolution="2", **kw)  # type: ignore[arg-type]


def test_ctc_mean_of_nothing() -> None:
    with pytest.raises(ValueError, match="values: expected at least one"):
        ctc_mean([])


def test_bd_rate_library_names_bad_points() -> None:
    with pytest.raises(TypeError, match=r"rate_a/psnr_a: point 1: expected a real rate, found '2'"):
        bd_rate([1, "2"], [30, 33], [1, 2], [30, 33])  # type: ignore[list-item]
    with pytest.raises(TypeError, match=r"rate_b/psnr_b: point 0: expected a real PSNR, found None"):
        bd_rate([1, 2], [30, 33], [1, 2], [None, 33])  # type: ignore[list-item]


def _curve(tmp_path: Path, name: str, text: str, bom: bool = False) -> str:
    p = tmp_path / name
    p.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.encode())
    return str(p)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        # the shared field-count check (it was "1 field(s) more than the header's 2 columns"; short rows read as None)
        ("rate,GridD1\n100,30,7\n200,33\n", "b.csv:2: expected 2 fields (the header's), found 3"),
        ("rate,GridD1\n100,30\n200\n", "b.csv:3: expected 2 fields (the header's), found 1"),
        ("rate,GridD1\n100,nan\n200,33\n", "b.csv:2: column 'GridD1': expected a finite PSNR"),
        ("rate,GridD1\n0,30\n200,33\n", "b.csv:2: column 'rate': expected a positive finite rate"),
        ("rate,GridD1\n100,30\n-2,33\n", "b.csv:3: column 'rate': expected a positive finite rate"),
        ("rate,GridD1\n100,30\n", "b.csv: expected at least 2 rate points (rows), found 1"),
        ("rate,GridD1\n", "b.csv: expected at least 2 rate points (rows), found 0"),
        ("rate,GridD1\n100,30\n200,30\n", "b.csv:3: column 'GridD1': PSNR 30.0 repeats line 2's"),
    ],
)
def test_bdrate_csv_errors_name_file_and_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str,
                                              message: str) -> None:  # fmt: skip
    a = _curve(tmp_path, "a.csv", "rate,GridD1\n100,30\n200,33\n400,36\n")
    assert main(["bdrate", a, _curve(tmp_path, "b.csv", text)]) == 1
    assert message in capsys.readouterr().err


def test_bdrate_accepts_bom_and_needs_no_torch(tmp_path: Path) -> None:
    a = _curve(tmp_path, "a.csv", "rate,GridD1\n100,30\n200,33\n400,36\n", bom=True)
    b = _curve(tmp_path, "b.csv", "rate,GridD1\n50,30\n100,33\n200,36\n", bom=True)
    code = ("import sys; from torchmeshmetric.cli import main; rc = main(['bdrate', sys.argv[1], sys.argv[2]]); "
            "print('torch' in sys.modules); sys.exit(rc)")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code, a, b], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[2])})  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["GridD1", "-50.0000", "%", "False"]
    np.testing.assert_allclose(bd_rate([100, 200, 400], [30, 33, 36], [50, 100, 200], [30, 33, 36]), -50.0)


@pytest.mark.parametrize("which", ["positions", "uvs"])
def test_dequantize_refuses_non_finite_and_complex(which: str) -> None:
    from torchmeshmetric.mpeg.ctc.dequantize import dequantize_positions, dequantize_uvs

    def call(x: np.ndarray) -> object:
        if which == "positions":
            return dequantize_positions(x, 10, [0, 0, 0], [1, 1, 1])
        return dequantize_uvs(x[:, :2], 10)

    name = "verts" if which == "positions" else "uvs"
    for bad in (np.nan, np.inf):
        x = np.array([[1.0, 2, 3], [4, bad, 6]])
        with pytest.raises(ValueError, match=f"{name}: expected finite quantised values, found 1 NaN or infinite"):
            call(x)
    with pytest.raises(TypeError, match=f"{name}: expected real integer values, found dtype complex128"):
        call(np.array([[1.0, 2, 3], [4, 5, 6]]) + 1j)


def test_ibsm_of_meshes_that_never_overlap_keeps_99_99_and_warns() -> None:
    from torchmeshmetric.mpeg.comparison.ibsm import IbsmNoOverlapWarning, ibsm

    tri = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    f = torch.tensor([[0, 1, 2]])
    a = TexturedMesh(Mesh(tri, f))
    b = TexturedMesh(Mesh(tri + torch.tensor([50.0, 50, 50]), f))
    with pytest.warns(IbsmNoOverlapWarning, match="no pixel is covered in both renderings"):
        r = ibsm(a, b, resolution=32, cameras=4)
    assert r.geo_psnr == 99.99 and r.pixels == 0 and r.unmatched_percent == 100.0


def test_ctc_frame_errors_name_ref_and_dis() -> None:
    q = TexturedMesh(Mesh(torch.tensor([[0.0, 0, 0], [9, 0, 0], [0, 9, 0]]), torch.tensor([[0, 1, 2]])))
    nan = TexturedMesh(Mesh(torch.tensor([[0.0, 0, 0], [9, 0, 0], [0, float("nan"), 0]]), torch.tensor([[0, 1, 2]]),
                            validate=False))  # fmt: skip
    kw = dict(qp=10, qt=0, min_pos=[0, 0, 0], max_pos=[1, 1, 1], resolution=1.0, grid_size=16, ibsm_resolution=None)
    with pytest.raises(ValueError, match=r"^dis: positions: expected finite quantised values"):
        ctc_frame(q, nan, **kw)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"^ref: expected a TexturedMesh"):
        ctc_frame(q.mesh, q, **kw)  # type: ignore[arg-type]
    uv = TexturedMesh(q.mesh, torch.zeros(1, 3, 2), np.zeros((2, 2, 3), np.uint8))
    with pytest.raises(ValueError, match=r"^decoded_qt: expected an integer bit depth"):  # a setting, named so
        ctc_frame(q, uv, decoded_qt=40, **kw)  # type: ignore[arg-type]


def test_texture_errors_name_the_option_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Review X F10: `texture: texture file 'x.png' not found` (which of the two?) in ctc-face-errors, and `frame 0:
    texture: cannot read texture ... (while running frame 0)` in ctc (the frame twice, the option not at all)."""
    args = _sequence(tmp_path)
    (tmp_path / "bad_000.png").write_text("not an image")
    (tmp_path / "bad_001.png").write_text("not an image")
    ctc = [*args, "--no-ibsm", "--reference-texture", str(tmp_path / "bad_%03d.png")]
    assert main(ctc) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    want = f"torchmeshmetric ctc: error: --reference-texture: cannot read texture {str(tmp_path / 'bad_000.png')!r}"
    assert err.startswith(want) and err.endswith("(while running frame 0)") and "frame 0: " not in err, err
    face = ["ctc-face-errors", "--reference", str(tmp_path / "src_000.obj"), "--decoded", str(tmp_path / "dec_000.obj"),
            "--qp", "10", "--qt", "0", "--min-pos", "-1 -1 -1", "--max-pos", "1 1 1", "--out", str(tmp_path / "fe"),
            "--decoded-texture", str(tmp_path / "none.png")]  # fmt: skip
    assert main(face) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("torchmeshmetric ctc-face-errors: error: --decoded-texture: texture file "), err
