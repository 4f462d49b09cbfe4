"""``torchmeshmetric mpeg REF DIS --mode equ``: mmetric's equality verdict, its exit status and JSON."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from torchmeshmetric._checks import DTypeError, IndexRangeError, ShapeError
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg import EqualityModel, mesh_equality

QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


def _write(tmp_path: Path, name: str, faces: str) -> str:
    p = tmp_path / name
    p.write_text(QUAD + faces)
    return str(p)


def test_equal_and_reordered(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = _write(tmp_path, "a.obj", "f 1 2 3\nf 1 3 4\n")
    b = _write(tmp_path, "b.obj", "f 3 4 1\nf 2 3 1\n")  # same triangles, other order and first corner
    c = _write(tmp_path, "c.obj", "f 1 3 2\nf 1 3 4\n")  # the first triangle reversed
    assert main(["mpeg", a, b, "--mode", "equ"]) == 0
    assert capsys.readouterr().out == "meshes are equal\n"
    assert main(["mpeg", a, c, "--mode", "equ"]) == 1
    assert capsys.readouterr().out.splitlines() == [
        "meshes are not equal, early return.",
        "triangle number 0 from A has no equivalent in B",
    ]
    assert main(["mpeg", a, c, "--mode", "equ", "--unoriented"]) == 0
    assert capsys.readouterr().out == "meshes are equal\n"
    assert main(["mpeg", a, c, "--mode", "equ", "--all-differences", "--json"]) == 1
    d = json.loads(capsys.readouterr().out)
    assert (d["equal"], d["different_triangles"], d["first_unmatched"], d["textures"]) == (False, 1, 0, [])
    assert (d["position_differences"], d["uv_differences"], d["color_differences"], d["normal_differences"]) == (
        0,
        0,
        0,
        0,
    )


def test_different_counts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = _write(tmp_path, "a.obj", "f 1 2 3\nf 1 3 4\n")
    b = _write(tmp_path, "b.obj", "f 1 2 3\n")
    assert main(["mpeg", a, b, "--mode", "equ"]) == 1
    assert capsys.readouterr().out == "meshes are not equal, number of triangles are different 2 vs 1\n"


def _textured(
    tmp_path: Path, name: str, texel: int, normals: str, colour3: str, corners: str, extra_vt: str = ""
) -> str:
    """The quad with a 2x2 texture (texel 0's red = ``texel``), four UVs, per-vertex colours and normals."""
    img = np.full((2, 2, 3), 200, dtype=np.uint8)
    img[0, 0, 0] = texel
    Image.fromarray(img).save(tmp_path / f"{name}.png")
    (tmp_path / f"{name}.mtl").write_text(f"newmtl m\nmap_Kd {name}.png\n")
    verts = QUAD.splitlines()
    verts = [f"{v} 0.5 0.5 0.5" for v in verts[:3]] + [f"{verts[3]} {colour3}"]
    text = (
        f"mtllib {name}.mtl\n" + "\n".join(verts) + "\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n" + extra_vt + normals + corners
    )
    p = tmp_path / f"{name}.obj"
    p.write_text(text)
    return str(p)


def test_every_line_of_a_hand_built_pair(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The lines mmetric v1.1.7's ``Compare::equ`` (source/lib/source/mmCompare.cpp) prints, without the binary.

    Its source gives each line: the maps first, RGB texel by texel, ``"texture maps are not equal: " << diffs <<
    "pixel differences"`` (no space); then the triangles, whose corners compare normals too when both models have
    one per position (``fetchTriangle(..., hasNormals, ...)``); with ``--earlyReturn=false`` the four lists, each
    ``|count A - count B|`` plus the rows that differ in their common prefix. Its OBJ reader keeps the ``vt`` lines as
    listed and drops every ``vn`` when a corner names one ("normals with separate index table are not yet
    supported").
    """
    up = "vn 0 0 1\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\n"
    tilted = "vn 0 0 1\nvn 0 0.6 0.8\nvn 0 0 1\nvn 0 0 1\n"
    plain, indexed = "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n", "f 1/1/1 2/2/2 3/3/3\nf 1/1/1 3/3/3 4/4/4\n"
    a = _textured(tmp_path, "a", 200, up, "0.5 0.5 0.5", plain)
    # one texel, the normal of vertex 2 (triangle 0), the colour of vertex 4 (triangle 1) and an unused fifth UV
    b = _textured(tmp_path, "b", 7, tilted, "1 0 0", plain, extra_vt="vt 0.5 0.5\n")
    assert main(["mpeg", a, b, "--mode", "equ", "--all-differences"]) == 1
    assert capsys.readouterr().out.splitlines() == [
        "texture maps are not equal: 1pixel differences",
        "meshes are not equal, 2 different triangles",
        "Position differences: 0",
        "UV coords differences: 1",
        "Colors differences: 1",
        "Normals differences: 1",
    ]
    assert main(["mpeg", a, b, "--mode", "equ"]) == 1
    assert capsys.readouterr().out.splitlines() == [
        "texture maps are not equal: 1pixel differences",
        "meshes are not equal, early return.",
        "triangle number 0 from A has no equivalent in B",
    ]
    # v/vt/vn corners: mmetric's reader drops the normals, so the tilted one no longer counts
    c = _textured(tmp_path, "c", 200, tilted, "0.5 0.5 0.5", indexed)
    assert main(["mpeg", a, c, "--mode", "equ", "--all-differences"]) == 0
    assert capsys.readouterr().out.splitlines() == ["texture maps are equal", "meshes are equal"]
    # the texture given on the command line replaces the MTL's; a model without any map: "mapB is null"
    d = _write(tmp_path, "d.obj", "f 1 2 3\nf 1 3 4\n")
    assert main(["mpeg", a, d, "--mode", "equ", "--dis-texture", str(tmp_path / "b.png")]) == 0
    assert capsys.readouterr().out.splitlines() == [
        "texture maps are not equal: 1pixel differences",
        "meshes are equal",
    ]
    assert main(["mpeg", a, d, "--mode", "equ", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["textures"] == ["mapB is null"]


def test_equality_model_tables_and_map_sets() -> None:
    """The model's tables are checked when built (naming the field); map sets of other sizes, or both empty, give
    mmetric's set-level lines (``Compare::equ``: "not of equal: size of set A ..." / "skipping texture maps
    comparison"), a per-position UV list is compared through the position indices."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    with pytest.raises(IndexRangeError, match=r"EqualityModel.triangles: expected indices of positions in \[0, 3\]"):
        EqualityModel(v, f + 1)
    with pytest.raises(ShapeError, match=r"EqualityModel.triangles_uv: expected 0 or 2 rows"):
        EqualityModel(v, f, uvs=np.zeros((4, 2)), triangles_uv=np.zeros((1, 3), np.int64))
    with pytest.raises(DTypeError, match=r"EqualityModel.textures\[0\]: expected an \(H, W, 3\) uint8"):
        EqualityModel(v, f, textures=(np.zeros((2, 2, 3)),))
    img = np.zeros((2, 2, 3), np.uint8)
    assert mesh_equality(EqualityModel(v, f, textures=()), EqualityModel(v, f, textures=())).report() == (
        "skipping texture maps comparison\nmeshes are equal"
    )
    two = EqualityModel(v, f, textures=(img, None))
    assert mesh_equality(two, EqualityModel(v, f, textures=(img,))).textures == ("set sizes",)
    assert mesh_equality(two, two).textures == ("equal",)  # a pair of null maps prints nothing
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    a, b = EqualityModel(v, f, uvs=uv), EqualityModel(v, f, uvs=uv[[0, 1, 2, 0]])
    assert a.has_uvs and mesh_equality(a, b).report(False).splitlines()[:4] == [
        "meshes are not equal, 1 different triangles",
        "Position differences: 0",
        "UV coords differences: 1",
        "Colors differences: 0",
    ]


@pytest.mark.parametrize("bad", ["vn nan nan nan", "vn 0 1"])
def test_normals_mm_drops_are_not_read(tmp_path: Path, capsys: pytest.CaptureFixture[str], bad: str) -> None:
    """Faces naming normals (``v//vn``): mmetric drops the normals, so a bad ``vn`` line there is no error (review P:
    such files compared before the normals were read, and were refused after); without the indices it still is."""
    quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    a = tmp_path / "a.obj"
    a.write_text(quad + bad + "\nf 1//1 2//1 3//1\nf 1//1 3//1 4//1\n")
    b = tmp_path / "b.obj"
    b.write_text(quad + "f 1 2 3\nf 1 3 4\n")
    assert main(["mpeg", "--mode", "equ", "--all-differences", str(a), str(b)]) == 0
    assert capsys.readouterr().out.strip() == "meshes are equal"
    c = tmp_path / "c.obj"
    c.write_text(quad + bad + "\nf 1 2 3\nf 1 3 4\n")
    assert main(["mpeg", "--mode", "equ", str(c), str(b)]) == 2  # an error: diff's 2, not "not equal"
    assert "line 5" in capsys.readouterr().err


def test_equality_model_values_beyond_float32_are_named() -> None:
    """Finite float64 values float32 cannot hold were reported as "NaN/Inf" after the cast, with a numpy warning."""
    import warnings

    from torchmeshmetric._checks import NonFiniteError

    big = np.array([[0.0, 0, 0], [1e39, 0, 0], [0, 1, 0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(NonFiniteError, match=r"EqualityModel.positions: expected values that fit float32 .*1e\+39"):
            EqualityModel(big, np.array([[0, 1, 2]]))
    with pytest.raises(NonFiniteError, match=r"EqualityModel.positions: expected finite values, found 1 NaN/Inf"):
        EqualityModel(np.array([[0.0, 0, 0], [np.nan, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))


def test_exit_status_is_diffs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """equ, eqTFAN and topo exit as ``diff`` does: 0 equal, 1 not equal, 2 trouble. An error exited 1 like "not
    equal" (an empty OBJ, a NaN point cloud the library refuses, a bad option once the command ran; review S §6);
    other modes keep 1 for an error, and argparse's refusals stay 2."""
    a = _write(tmp_path, "a.obj", "f 1 2 3\n")
    b = _write(tmp_path, "b.obj", "f 1 2 4\n")
    empty = tmp_path / "e.obj"
    empty.write_text("")
    nan = tmp_path / "n.obj"
    nan.write_text("v nan 0 0\n")
    maps = tmp_path / "m.txt"
    maps.write_text("0 0\n")
    for mode in ("equ", "eqTFAN"):
        assert main(["mpeg", "--mode", mode, a, a]) == 0
        assert main(["mpeg", "--mode", mode, a, b]) == 1
        assert main(["mpeg", "--mode", mode, str(empty), a]) == 2
        assert main(["mpeg", "--mode", mode, str(nan), str(nan), "--epsilon", "0.1"]) == 2
        assert main(["mpeg", "--mode", mode, a, a, "--epsilon", "-1"]) == 2
        with pytest.raises(SystemExit) as refused:  # argparse's refusal, as ever
            main(["mpeg", "--mode", mode, a, a, "--epsilon", "x"])
        assert refused.value.code == 2
    assert main(["mpeg", "--mode", "topo", a, a]) == 2  # no maps
    assert main(["mpeg", "--mode", "topo", a, a, "--face-map", str(maps), "--vertex-map", str(tmp_path / "no")]) == 2
    assert main(["mpeg", "--mode", "pcc", str(empty), a]) == 1  # not a comparison mode: an error is 1
    err = capsys.readouterr().err
    assert err.count("torchmeshmetric mpeg: error: ") >= 10
