"""Models without faces (point clouds) in ``mesh_equality`` / ``tfan_equality`` and ``torchmeshmetric mpeg --mode
equ/eqTFAN``: mmetric's sorted-vertex comparison (checked against the ``mm`` binary in
``test_point_cloud_equality_against_mm.py``), its readers, its errors. No binary needed here."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from torchmeshmetric.cli import main
from torchmeshmetric.data.mesh_file import MeshFileError
from torchmeshmetric.data.ply import read_ply_point_arrays, read_ply_points
from torchmeshmetric.mpeg import EqualityModel, load_equality_model, mesh_equality, tfan_equality
from torchmeshmetric.mpeg.comparison.equality import point_cloud_verdict

CLOUD = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
NONE = np.zeros((0, 3), np.int64)


def _naive(a: np.ndarray, b: np.ndarray, epsilon: float) -> tuple[bool, int | None]:
    """The branch written out: Python's tuple sort, then float comparisons one by one (float32 arithmetic)."""
    sa = sorted(tuple(float(x) for x in p) for p in np.asarray(a, np.float32))
    sb = sorted(tuple(float(x) for x in p) for p in np.asarray(b, np.float32))
    if epsilon == 0:
        return sa == sb, None
    if len(sa) != len(sb):
        return False, None
    count = 0
    for p, q in zip(sa, sb, strict=True):
        d = [np.float32(x) - np.float32(y) for x, y in zip(p, q, strict=True)]
        length = np.sqrt((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2])
        count += bool(length >= np.float32(epsilon))
    return count == 0, count


def test_verdict_against_a_naive_reference() -> None:
    rng = np.random.default_rng(5)
    grid = np.array([-1, -0.0, 0, 0.5, 2], np.float32)
    for n in (1, 3, 8, 30):
        a = rng.choice(grid, size=(n, 3))
        b = a[rng.permutation(n)]
        moved = b.copy()
        moved[: max(1, n // 3)] += np.float32(0.25)
        for other in (b, moved, b[:-1], np.concatenate([b, b[:1]])):
            for eps in (0.0, 0.1, 0.25, 0.5, 3.0):
                assert point_cloud_verdict(a, other, eps) == _naive(a, other, eps), (n, eps)


def test_verdict_cases() -> None:
    assert point_cloud_verdict(CLOUD, CLOUD[::-1]) == (True, None)
    assert point_cloud_verdict(CLOUD, -CLOUD * 0) == (False, None)  # -0.0 == 0.0, but 4 zeros are not the cloud
    assert point_cloud_verdict(np.zeros((2, 3)), -np.zeros((2, 3))) == (True, None)
    assert point_cloud_verdict(CLOUD, CLOUD[:3]) == (False, None)  # different counts: not equal
    assert point_cloud_verdict(CLOUD, CLOUD[:3], 0.5) == (False, None)  # ... with an epsilon too, nothing counted
    shifted = CLOUD + np.float32([0, 0, 0.5])
    assert point_cloud_verdict(CLOUD, shifted, 0.5) == (False, 4)  # length == epsilon differs (>=)
    assert point_cloud_verdict(CLOUD, shifted, 0.5000001) == (True, 0)
    big = np.array([[3e38, 0, 0]], np.float32)
    assert point_cloud_verdict(big, -big, 1.0) == (False, 1)  # the difference overflows: an infinite distance
    assert point_cloud_verdict(CLOUD, CLOUD, 1e-50) == (True, None)  # 0 as float32: mm's exact branch


@pytest.mark.parametrize(
    ("epsilon", "error", "message"),
    [
        (-0.5, ValueError, r"^epsilon: expected a finite float32 distance >= 0, found -0.5"),
        (float("nan"), ValueError, r"^epsilon: expected a finite float32 distance >= 0, found nan"),
        (float("inf"), ValueError, r"^epsilon: expected a finite float32 distance >= 0, found inf"),
        (1e39, ValueError, r"^epsilon: expected a finite float32 distance >= 0, found 1e\+39"),
        ("0.1", TypeError, r"^epsilon: expected a float, found str"),
        (True, TypeError, r"^epsilon: expected a float, found bool"),
    ],
)
def test_bad_epsilon_is_refused_for_clouds_and_meshes(epsilon: object, error: type, message: str) -> None:
    mesh = EqualityModel(CLOUD, np.array([[0, 1, 2]]))
    with pytest.raises(error, match=message):
        point_cloud_verdict(CLOUD, CLOUD, epsilon)  # type: ignore[arg-type]
    for compare in (mesh_equality, tfan_equality):
        with pytest.raises(error, match=message):
            compare(mesh, mesh, epsilon=epsilon)  # type: ignore[operator]


def test_results_and_reports() -> None:
    a, b = EqualityModel(CLOUD, NONE), EqualityModel(CLOUD[[3, 1, 2, 0]] + np.float32([0.1, 0, 0]), NONE)
    r = mesh_equality(a, b, epsilon=0.05)
    assert (r.points, r.equal, r.point_differences, r.different_triangles, r.first_unmatched) == (
        True, False, 4, None, None,
    )  # fmt: skip
    assert r.report() == r.report(early_return=False) == "model vertices are not equals, found 4 differences"
    assert mesh_equality(a, b, unoriented=True).report() == "model vertices are not equals"
    assert mesh_equality(a, b, epsilon=0.2).report() == "model vertices are equals"
    t = tfan_equality(a, b, epsilon=0.05)
    assert (t.points, t.equal, t.point_differences, t.geometry) == (True, False, 4, None)
    assert t.report() == "model vertices are not equals, found 4 differences"
    img = np.zeros((2, 2, 3), np.uint8)
    with_map = EqualityModel(CLOUD, NONE, textures=(img,))
    assert mesh_equality(with_map, a).report() == "texture maps are not equal: mapB is null\nmodel vertices are equals"
    assert tfan_equality(with_map, a).report() == "texture maps are not equal: mapB is null\nmodel vertices are equals"
    # a Mesh-like form without faces is a point cloud too
    assert mesh_equality((torch.from_numpy(CLOUD), torch.from_numpy(NONE)), a).equal
    # epsilon changes nothing for meshes, as in mm
    mesh = EqualityModel(CLOUD, np.array([[0, 1, 2]]))
    moved = EqualityModel(CLOUD + np.float32(1e-3), np.array([[0, 1, 2]]))
    assert mesh_equality(mesh, moved, epsilon=1.0).report() == mesh_equality(mesh, moved).report()


# ----------------------------------------------------------------------------------------------- readers
def _ply(path: Path, binary: bool, n: int = 3) -> Path:
    pts = CLOUD[:n]
    props = "".join(f"property float {c}\n" for c in ("x", "y", "z", "nx", "ny", "nz", "texture_u", "texture_v"))
    props += "".join(f"property uchar {c}\n" for c in ("red", "green", "blue"))
    fmt = "binary_little_endian" if binary else "ascii"
    head = f"ply\nformat {fmt} 1.0\nelement vertex {n}\n{props}element face 0\nproperty list uchar int vertex_indices\n"
    head += "end_header\n"
    dtype = [(c, "<f4") for c in ("x", "y", "z", "nx", "ny", "nz", "u", "v")] + [(c, "u1") for c in "rgb"]
    rows = np.zeros(n, dtype)
    for k, c in enumerate("xyz"):
        rows[c] = pts[:, k]
    rows["nz"], rows["u"], rows["r"] = 1, 0.5, np.arange(n) * 10
    if binary:
        path.write_bytes(head.encode() + rows.tobytes())
    else:
        path.write_text(head + "".join(" ".join(f"{v:g}" for v in r.tolist()) + "\n" for r in rows))
    return path


@pytest.mark.parametrize("binary", [False, True])
def test_ply_point_clouds_are_read_with_their_attributes(tmp_path: Path, binary: bool) -> None:
    p = _ply(tmp_path / "c.ply", binary)
    arrays = read_ply_point_arrays(p)
    assert arrays is not None and arrays.faces.shape == (0, 3)
    np.testing.assert_array_equal(arrays.verts, CLOUD[:3])
    assert arrays.normals[:, 2].tolist() == [1, 1, 1] and arrays.uvs[:, 0].tolist() == [0.5] * 3
    assert arrays.colors[:, 0].tolist() == [0, 10, 20]
    verts, _ = read_ply_points(p)  # the older two-array form is the same reader
    np.testing.assert_array_equal(verts, arrays.verts)
    m = load_equality_model(p)
    assert (len(m.triangles), len(m.positions), len(m.normals), len(m.uvs), len(m.colors)) == (0, 3, 3, 3, 3)


def test_obj_point_clouds(tmp_path: Path) -> None:
    p = tmp_path / "c.obj"
    p.write_text("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nvn 0 0 1\nvt 0.5 0.5\n")
    m = load_equality_model(p)
    assert (len(m.triangles), len(m.positions), len(m.colors), len(m.normals), len(m.uvs)) == (0, 2, 2, 1, 1)
    assert m.colors[0].tolist() == [255, 0, 0]


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("vt 0 0\n", r"has no vertices and no faces \(mmetric refuses it too\)"),
        ("v nan 0 0\nv 1 0 0\n", r"vertex 0 \(line 1\) has non-finite coordinates"),
        ("v 0 0 0\nv inf 0 0\n", r"vertex 1 \(line 2\) has non-finite coordinates"),
        ("v 0 0 1e39\n", r"line 1: vertex 0 has coordinates up to 1e\+39"),
        ("v 0 0 0\nv 1 0 0\nf 1 2\n", r"line 3 has a face with 2 corners; expected triangles"),
    ],
)
def test_bad_obj_point_clouds_are_refused(tmp_path: Path, content: str, message: str) -> None:
    p = tmp_path / "c.obj"
    p.write_text(content)
    with pytest.raises(MeshFileError, match=message):
        load_equality_model(p)


def test_bad_ply_point_clouds_are_refused(tmp_path: Path) -> None:
    p = tmp_path / "c.ply"
    p.write_text(
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    )
    with pytest.raises(MeshFileError, match=r"has no vertices and no faces"):
        load_equality_model(p)
    p.write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                 "end_header\nnan 0 0\n")  # fmt: skip
    with pytest.raises(MeshFileError, match=r"vertex 0 \(line 8\) has non-finite coordinates"):
        load_equality_model(p)


# ----------------------------------------------------------------------------------------------- command line
def test_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, b, m = tmp_path / "a.obj", tmp_path / "b.ply", tmp_path / "m.obj"
    a.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    _ply(b, binary=True)
    m.write_text(a.read_text() + "f 1 2 3\n")
    for mode in ("equ", "eqTFAN"):
        assert main(["mpeg", str(a), str(b), "--mode", mode]) == 0
        assert capsys.readouterr().out == "model vertices are equals\n"
        assert main(["mpeg", str(a), str(m), "--mode", mode]) == 1
        assert capsys.readouterr().out == "meshes are not equal, number of triangles are different 0 vs 1\n"
    c = tmp_path / "c.obj"
    c.write_text("v 0 0 0.25\nv 1 0 0\nv 0 1 0\n")
    assert main(["mpeg", str(a), str(c), "--mode", "equ"]) == 1
    assert capsys.readouterr().out == "model vertices are not equals\n"
    assert main(["mpeg", str(a), str(c), "--mode", "eqTFAN", "--epsilon", "0.25"]) == 1
    assert capsys.readouterr().out == "model vertices are not equals, found 1 differences\n"
    assert main(["mpeg", str(a), str(c), "--mode", "equ", "--epsilon", "0.3", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert (d["points"], d["equal"], d["point_differences"]) == (True, True, 0)
    assert main(["mpeg", str(a), str(c), "--mode", "equ", "--epsilon", "-1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("torchmeshmetric mpeg: error: --epsilon: expected a finite float32 distance >= 0, found -1.0")
