"""``torchmeshmetric mpeg REF DIS``: JSON keys and values (against mmetric's figures), table, typed errors."""

from __future__ import annotations

import json
import math
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.mpeg.conftest import MM, MPEG_REF
from torchmeshmetric.cli import main

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def _write(tmp_path: Path, name: str, text: str) -> str:
    p = tmp_path / name
    p.write_text(text)
    return str(p)


@pytest.mark.skipif(not (MPEG_REF / "expected.json").is_file(), reason="../shared/reference/mpeg absent")
def test_json_mesh_sampling_equals_mmetric(capsys: pytest.CaptureFixture[str]) -> None:
    exp = json.loads((MPEG_REF / "expected.json").read_text())["torus/simplified10.obj"]["vertex"]
    ref, dis = MPEG_REF / "torus" / "ref.obj", MPEG_REF / "torus" / "simplified10.obj"
    assert main(["mpeg", str(ref), str(dis), "--sampling", "mesh", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    for key in ("d1_psnr", "d2_psnr", "d1_mse", "d2_mse", "d1_hausdorff", "d2_hausdorff", "peak"):
        assert key in d
    assert set(d["ref_to_dis"]) >= {"d1_mse", "d2_mse", "d1_psnr", "d2_psnr"}
    assert "y_psnr" not in d  # no colour on either mesh
    assert abs(d["d1_psnr"] - exp["psnrF_p2point"]) <= 0.01
    assert abs(d["d2_psnr"] - exp["psnrF_p2plane"]) <= 0.01
    assert abs(d["d1_mse"] - exp["mseF_p2point"]) <= 1e-6 * exp["mseF_p2point"]
    assert abs(d["ref_to_dis"]["d2_mse"] - exp["mse1_p2plane"]) <= 1e-6 * exp["mse1_p2plane"]
    assert abs(d["dis_to_ref"]["d1_mse"] - exp["mse2_p2point"]) <= 1e-6 * exp["mse2_p2point"]
    assert (d["points_ref"], d["points_dis"]) == (exp["points_ref"], exp["points_dis"])


@pytest.mark.skipif(not (MPEG_REF / "textured").is_dir(), reason="../shared/reference/mpeg absent")
def test_json_colour_keys(capsys: pytest.CaptureFixture[str]) -> None:
    exp = json.loads((MPEG_REF / "textured" / "expected.json").read_text())["coarse.obj"]["vertex"]
    ref, dis = MPEG_REF / "textured" / "ref.obj", MPEG_REF / "textured" / "coarse.obj"
    assert main(["mpeg", str(ref), str(dis), "--sampling", "mesh", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    for ours, theirs in (("y_psnr", "psnrF_y"), ("cb_psnr", "psnrF_cb"), ("cr_psnr", "psnrF_cr")):
        assert abs(d[ours] - exp[theirs]) <= 0.01


@pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
@pytest.mark.skipif(not (MPEG_REF / "torus").is_dir(), reason="../shared/reference/mpeg absent")
def test_table_prints_mmetrics_digits(capsys: pytest.CaptureFixture[str]) -> None:
    """The table printed MSE and Hausdorff with 4 decimals (d1_mse 0.0062, d1_hausdorff 0.0718) where mmetric prints
    9 significant digits (review B #9): every symmetric figure is now mm's printed text."""
    ref, dis = MPEG_REF / "torus" / "ref.obj", MPEG_REF / "torus" / "hole.obj"
    args = [str(MM), "compare", "--mode", "pcc", "--hausdorff", "--inputModelA", str(ref), "--inputModelB", str(dis)]
    mm = subprocess.run(args, capture_output=True, text=True, timeout=300, check=True).stdout
    found = re.findall(r"^\s*(mseF|mseF,PSNR|h\.,PSNR)\s+\((p2point|p2plane)\): (\S+)$", mm, re.M)
    printed = {(name, kind): value for name, kind, value in found}
    assert len(printed) == 6
    assert main(["mpeg", str(ref), str(dis), "--sampling", "mesh"]) == 0
    table = {line.split()[0]: line.split()[1] for line in capsys.readouterr().out.splitlines()[1:-1]}
    for ours, theirs in (
        ("d1_mse", ("mseF", "p2point")),
        ("d2_mse", ("mseF", "p2plane")),
        ("d1_psnr", ("mseF,PSNR", "p2point")),
        ("d2_psnr", ("mseF,PSNR", "p2plane")),
        ("d1_hausdorff_psnr", ("h.,PSNR", "p2point")),
        ("d2_hausdorff_psnr", ("h.,PSNR", "p2plane")),
    ):
        assert table[ours] == printed[theirs], ours
    assert table["d1_mse"] == "0.006184389" and table["d1_hausdorff"] == "0.0717588479"


def test_identical_meshes_json_inf_and_table(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tri = _write(tmp_path, "t.obj", TRI)
    assert main(["mpeg", tri, tri, "--grid-size", "16", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)  # strict JSON: infinity as a string
    assert d["d1_psnr"] == "inf" and d["d2_psnr"] == "inf"
    assert d["d1_mse"] == 0.0 and d["points_ref"] == d["points_dis"] > 0
    assert math.isclose(d["peak"], math.sqrt(2.0), rel_tol=1e-6)
    assert main(["mpeg", tri, tri, "--grid-size", "16"]) == 0
    table = capsys.readouterr().out
    assert "d1_psnr" in table and "inf" in table and "(grid)" in table


@pytest.mark.parametrize(
    ("ref_text", "dis_text", "extra", "message"),
    [
        # the messages of the library's one OBJ reader (load_mesh gives the same ones)
        (TRI, "", [], "dis.obj' is empty (0 bytes)"),
        (TRI, "v 0 0 0\nv 1 0 0\nv 0 1 0\n", [], "dis.obj' has no faces (3 vertices)"),
        (TRI, "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", [], "dis.obj' vertex 0 (line 1) has non-finite coordinates"),
        (TRI, "v 0 0 1e39\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", [], "dis.obj' line 1: vertex 0 has coordinates up to 1e+39"),
        (TRI, TRI.replace("f 1 2 3", "vt nan nan\nf 1/1 2/1 3/1"), [], "texture coordinate 0 (line 4) is not finite"),
        (TRI, TRI, ["--grid-size", "0"], "error: --grid-size: expected an integer in 2..1048576, found 0"),
        # review X F4: numpy's "RuntimeWarning: invalid value encountered in cast" came first, then the memory error
        (
            TRI,
            TRI,
            ["--grid-size", "99999999999999999999"],
            "error: --grid-size: expected an integer in 2..1048576, found 99999999999999999999\n",
        ),
        # -1e39 is finite, but not in float32 (mm's box): "RuntimeWarning: overflow ..." then "found [-inf, ...]"
        (
            TRI,
            TRI,
            ["--box", "-1e39 -1 -1", "1 1 1"],
            "error: --box MIN: '-1e39 -1 -1' is beyond float32's range (mmetric reads the box as float32)\n",
        ),
        (TRI, TRI, ["--box", "0 0 0", "0.5 0.5 0.5"], "does not contain the reference mesh"),
        (TRI, TRI, ["--box", "0 0", "1 1 1"], "--box MIN: expected three finite numbers"),
        (TRI, TRI, ["--box", "1 1 1", "0 0 0"], "max corner [0.0, 0.0, 0.0] is below min corner"),
        (TRI, TRI, ["--peak", "0"], "error: --peak: expected a positive finite number, found 0.0"),
        # the library's argument names (path, texture, resolution) were printed for the command's (found by review)
        (TRI, TRI.replace("f 1 2 3", "f 1 2 4"), [], "error: DIS: '"),
        (TRI, TRI, ["--ref-texture", "none.png"], "error: --ref-texture: texture file "),
        (
            TRI,
            TRI,
            ["--mode", "ibsm", "--ibsm-resolution", "0"],
            "error: --ibsm-resolution: expected an integer in 1..32768, found 0",
        ),
        # 2**32 + 64 was narrowed to an int in the rasterizer: computed at 64, exit 0, the CSV row said 4294967360
        # (review X F20); 99999999 was an OOM kill (F5)
        (
            TRI,
            TRI,
            ["--mode", "ibsm", "--ibsm-resolution", "4294967360"],
            "error: --ibsm-resolution: expected an integer in 1..32768, found 4294967360",
        ),
        (
            TRI,
            TRI,
            ["--mode", "ibsm", "--ibsm-resolution", "99999999"],
            "error: --ibsm-resolution: expected an integer in 1..32768, found 99999999",
        ),
        (TRI, TRI, ["--mode", "ibsm", "--ibsm-cameras", "1"], "error: --ibsm-cameras: expected an int >= 2, found 1"),
        (TRI.replace("f 1 2 3", "f 1 2 4"), TRI, ["--mode", "pcqm"], "error: REF: '"),
        (TRI, TRI.replace("f 1 2 3", "f 1 2 4"), ["--mode", "eqTFAN"], "error: DIS: '"),
        (TRI.replace("f 1 2 3", "f 1 2 4"), TRI, ["--mode", "equ"], "error: REF: '"),
    ],
)
def test_bad_input_is_one_clear_line(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    ref_text: str,
    dis_text: str,
    extra: list[str],
    message: str,
) -> None:
    ref = _write(tmp_path, "ref.obj", ref_text)
    dis = _write(tmp_path, "dis.obj", dis_text)
    comparison = any(m in extra for m in ("equ", "eqTFAN", "topo"))
    assert main(["mpeg", ref, dis, *extra]) == (2 if comparison else 1)  # diff's 2 for the comparison modes
    err = capsys.readouterr().err
    assert err.startswith("torchmeshmetric mpeg: error: ")  # no warning line before it
    assert message in err


def _cloud_ply(path: Path, points: np.ndarray, colors: np.ndarray) -> str:
    head = f"ply\nformat ascii 1.0\nelement vertex {len(points)}\n" + "".join(f"property float {c}\n" for c in "xyz")
    head += "".join(f"property uchar {c}\n" for c in ("red", "green", "blue"))
    pairs = zip(points.tolist(), colors.tolist(), strict=True)
    rows = "".join(f"{x!r} {y!r} {z!r} {r} {g} {b}\n" for (x, y, z), (r, g, b) in pairs)
    path.write_text(head + "end_header\n" + rows)
    return str(path)


def _clouds(tmp_path: Path) -> tuple[str, str]:
    rng = np.random.default_rng(0)
    a = rng.random((500, 3)).astype(np.float32)
    b = (a + rng.normal(0, 0.01, a.shape)).astype(np.float32)
    ca = rng.integers(0, 256, (500, 3))
    cb = np.clip(ca + rng.integers(-10, 10, (500, 3)), 0, 255)
    return _cloud_ply(tmp_path / "a.ply", a, ca), _cloud_ply(tmp_path / "b.ply", b, cb)


@pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
def test_point_cloud_plys_are_compared_as_mm_compares_them(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Point-cloud PLYs (mm sample's output) were refused in pcc mode ("holds a PointCloud, not a triangle mesh",
    review K); mm compare --mode pcc takes them as they are, and so does --sampling mesh now: mm's printed digits."""
    ref, dis = _clouds(tmp_path)
    args = [str(MM), "compare", "--mode", "pcc", "--inputModelA", ref, "--inputModelB", dis]
    mm = subprocess.run(args, capture_output=True, text=True, timeout=300, check=True).stdout
    found = dict(re.findall(r"^\s*(mseF\s+\(p2point\)|mseF,PSNR \(p2point\)|c\[\d\],PSNRF\s*): (\S+)$", mm, re.M))
    printed = {re.sub(r"\s+", " ", k).strip(): v for k, v in found.items()}
    assert len(printed) == 5, mm
    assert main(["mpeg", ref, dis, "--sampling", "mesh"]) == 0
    table = {line.split()[0]: line.split()[1] for line in capsys.readouterr().out.splitlines()[1:-1]}
    for ours, theirs in (
        ("d1_mse", "mseF (p2point)"),
        ("d1_psnr", "mseF,PSNR (p2point)"),
        ("y_psnr", "c[0],PSNRF"),
        ("cb_psnr", "c[1],PSNRF"),
        ("cr_psnr", "c[2],PSNRF"),
    ):
        assert table[ours] == printed[theirs], ours
    assert table["d1_psnr"] == "44.8246519"


def test_point_cloud_in_grid_mode_names_the_file_and_the_way(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ref, dis = _clouds(tmp_path)
    assert main(["mpeg", ref, dis]) == 1
    err = capsys.readouterr().err
    assert f"REF {ref!r}: a point cloud (500 points, no faces) has no surface for grid sampling" in err
    assert "--sampling mesh" in err


@pytest.mark.parametrize(
    ("extra", "line"),
    [
        # review X F3: each was dropped without a word (--box in mesh mode gave peak 3.46, the reference's box, where
        # the same box in grid mode gives 6.93), while --output-csv in equ mode was refused: one policy now
        (
            ["--sampling", "mesh", "--box", "-2 -2 -2", "2 2 2"],
            "--box: used in --mode pcc --sampling grid only, not in --mode pcc --sampling mesh; mesh mode's peak is "
            "the reference cloud's box diagonal: give --peak to fix the peak",
        ),
        (
            ["--sampling", "mesh", "--grid-size", "0"],
            "--grid-size: used in --mode pcc --sampling grid only, not in --mode pcc --sampling mesh; mesh mode "
            "samples by mm compare's subdivision, without a grid",
        ),
        (
            ["--sampling", "mesh", "--nearest"],
            "--nearest: used in --mode pcc --sampling grid only, not in --mode pcc --sampling mesh; mesh mode filters "
            "textures as mm compare --mode pcc does",
        ),
        (
            ["--mode", "equ", "--box", "1 1 1", "-1 -1 -1"],
            "--box: used in --mode pcc --sampling grid only, not in --mode equ",
        ),
        (["--face-map", "missing.txt"], "--face-map: used in --mode topo only, not in --mode pcc --sampling grid"),
        (
            ["--mode", "ibsm", "--radius-curvature", "1"],
            "--radius-curvature: used in --mode pcqm only, not in --mode ibsm",
        ),
        (
            ["--mode", "pcqm", "--ibsm-resolution", "64"],
            "--ibsm-resolution: used in --mode ibsm only, not in --mode pcqm",
        ),
        (
            ["--mode", "pcqm", "--peak", "3"],
            "--peak: used in --mode pcc only, not in --mode pcqm; the other modes have no PSNR peak (mm compare "
            "--resolution)",
        ),
        (["--mode", "topo", "--epsilon", "0.1"], "--epsilon: used in --mode equ and eqTFAN only, not in --mode topo"),
        (
            ["--all-differences"],
            "--all-differences: used in --mode equ and eqTFAN only, not in --mode pcc --sampling grid",
        ),
        (["--mode", "ibsm", "--sampling", "mesh"], "--sampling: used in --mode pcc only, not in --mode ibsm"),
        (
            ["--mode", "eqTFAN", "--unoriented"],
            "--unoriented: used in --mode equ only, not in --mode eqTFAN; eqTFAN compares oriented triangle fans (mm "
            "v1.1.7 ignores --eqTFAN_unoriented)",
        ),
        (
            ["--mode", "equ", "--output-csv", "s.csv"],
            "--output-csv: used in --mode pcc, ibsm and pcqm only, not in --mode equ; mmetric v1.1.7 writes the text "
            "TODO where a verdict would be; the exit status and --json give it",
        ),
    ],
)
def test_options_of_another_mode_are_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], line: str
) -> None:
    ref = _write(tmp_path, "ref.obj", TRI)
    missing = str(tmp_path / "missing.obj")  # refused before DIS is read: the option's line, not the missing file's
    comparison = any(m in extra for m in ("equ", "eqTFAN", "topo"))
    assert main(["mpeg", ref, missing, *extra]) == (2 if comparison else 1)
    assert capsys.readouterr().err == f"torchmeshmetric mpeg: error: {line}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ref.obj"]  # no CSV, no model


def test_options_of_the_mode_still_act(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The defaults filled in after the check are the documented ones, and the given values act."""
    tri = _write(tmp_path, "t.obj", TRI)
    assert main(["mpeg", tri, tri, "--grid-size", "16", "--box", "-2 -2 -2", "2 2 2", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["grid_size"] == 16 and math.isclose(d["peak"], math.sqrt(48.0), rel_tol=1e-6)  # the box's diagonal
    assert main(["mpeg", tri, tri, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["grid_size"] == 1024


def test_a_number_beyond_float64_is_quoted_as_given(capsys: pytest.CaptureFixture[str]) -> None:
    """Review X F4: --peak 1e400 said "found inf", not what the user typed; refused when parsed now (exit 2)."""
    with pytest.raises(SystemExit) as exit_info:
        main(["mpeg", "a.obj", "b.obj", "--peak", "1e400"])
    assert exit_info.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1].endswith("argument --peak: expected a finite number, found '1e400'")
