"""``--output-model-ref/dis`` in equ, eqTFAN, topo and pcqm modes and as OBJ in pcc mode, against files ``mm`` wrote.

The files in ``tests/data/mmetric/outputs`` are ``mm`` v1.1.7's (README there), so these run in every clone; the
same cases against the binary itself are in ``test_comparison_models_against_mm.py``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.mpeg.conftest import MM_TESTS
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg.comparison.point_order import _introsort, lexicographic_order, mmetric_point_order

OUT = MM_TESTS / "outputs"


def _run(tmp: Path, mode: str, a: Path, b: Path, ref: str, dis: str, *extra: str) -> int:
    args = ["mpeg", str(a), str(b), "--mode", mode, "--output-model-ref", str(tmp / ref)]
    return main([*args, "--output-model-dis", str(tmp / dis), *extra])


@pytest.mark.parametrize("mode", ["equ", "eqTFAN"])
def test_sorted_point_clouds(tmp_path: Path, mode: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Two point clouds: mm writes their positions sorted (no colour, no normal), ties placed by its std::sort."""
    a, b = OUT / "cloud_a.obj", OUT / "cloud_b.ply"
    assert _run(tmp_path, mode, a, b, "sorted_a.ply", "sorted_b.obj") == 1  # one point moved: not equal
    assert _run(tmp_path, mode, a, b, "sorted_a.obj", "sorted_b.ply") == 1
    for name in ("sorted_a.ply", "sorted_b.obj", "sorted_a.obj", "sorted_b.ply"):
        assert (tmp_path / name).read_bytes() == (OUT / name).read_bytes(), name
    assert "model vertices are not equals" in capsys.readouterr().out


def test_signed_zero_ties_need_mm_sort() -> None:
    """The stored cloud's ties mix -0 and 0: a stable sort writes another file than mm's; the introsort writes its."""
    from torchmeshmetric.mpeg.comparison.equality import load_equality_model

    p = load_equality_model(OUT / "cloud_a.obj").positions
    _, stable = lexicographic_order(p)
    order = mmetric_point_order(p)
    assert not np.array_equal(stable, order)
    rows = [" ".join(f"{v:.9g}" for v in r) for r in p[order].astype(np.float64).tolist()]
    assert rows == [line.rstrip() for line in (OUT / "sorted_a.ply").read_text().splitlines()[8:]]


def test_introsort_sorts() -> None:
    """libstdc++'s introsort sorts whatever the ranks (many ties, sorted, reversed input; past its 16-element runs)."""
    rng = np.random.default_rng(0)
    for rank in (rng.integers(0, 3, 500), np.arange(300), np.arange(300)[::-1], rng.integers(0, 10**6, 1000)):
        order = _introsort(rank.tolist())
        assert sorted(order) == list(range(len(rank)))
        assert np.all(np.diff(rank[order]) >= 0)


@pytest.mark.parametrize("mode", ["equ", "eqTFAN"])
def test_meshes_write_empty_models(tmp_path: Path, mode: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Meshes: mm writes the models it left empty (a PLY header with normals and colours; an OBJ's mtllib line)."""
    assert _run(tmp_path, mode, MM_TESTS / "plane.obj", MM_TESTS / "plane_qp8.obj", "e.obj", "e.ply") == 1
    assert (tmp_path / "e.obj").read_bytes() == (OUT / "empty_plane.obj").read_bytes()
    assert (tmp_path / "e.ply").read_bytes() == (OUT / "empty.ply").read_bytes()
    assert _run(tmp_path, mode, MM_TESTS / "plane_qp8.obj", MM_TESTS / "plane.obj", "f.obj", "f.ply") == 1
    assert (tmp_path / "f.obj").read_text() == "\n"  # no mtllib line: the header is empty
    capsys.readouterr()


def test_topology_writes_empty_models(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    faces, verts = tmp_path / "f.txt", tmp_path / "v.txt"
    faces.write_text("0 0\n1 1\n2 2\n3 3\n")  # mmetric's plane_shifted maps (test-compare-topo.sh)
    verts.write_text("0 0\n1 3\n2 2\n3 1\n4 4\n")
    maps = ("--face-map", str(faces), "--vertex-map", str(verts))
    a, b = MM_TESTS / "plane.obj", MM_TESTS / "plane_shifted.obj"
    assert _run(tmp_path, "topo", a, b, "e.obj", "e.ply", *maps) == 0
    assert (tmp_path / "e.obj").read_bytes() == (OUT / "empty_plane.obj").read_bytes()
    assert (tmp_path / "e.ply").read_bytes() == (OUT / "empty.ply").read_bytes()
    capsys.readouterr()


@pytest.mark.parametrize("mode", ["pcc", "pcqm"])
def test_sampled_cloud_as_obj(tmp_path: Path, mode: str, capsys: pytest.CaptureFixture[str]) -> None:
    """pcc (mesh sampling) and pcqm sample a mesh alike: the cloud as OBJ (mtllib kept, colours / 255, vn rows)."""
    extra = ("--sampling", "mesh") if mode == "pcc" else ()
    a = MM_TESTS / "plane.obj"
    assert _run(tmp_path, mode, a, MM_TESTS / "plane_qp8.obj", "c.obj", "c.ply", *extra) == 0
    assert (tmp_path / "c.obj").read_bytes() == (OUT / "pcc_plane.obj").read_bytes()
    capsys.readouterr()


def test_point_cloud_ply_keeps_its_normals(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A PLY cloud with normals (mm sample's output) passes through with them: mm's D2 uses them, and mm writes the
    file back as it was. They were dropped: D2 PSNR was nan, mm's 66.3524367 (66.5918393 DIS to REF)."""
    clouds = []
    for name in ("sphere", "sphere_qp8"):
        clouds.append(tmp_path / f"{name}.ply")
        assert main(["sample", str(MM_TESTS / f"{name}.obj"), str(clouds[-1]), "--resolution", "16"]) == 0
    capsys.readouterr()
    ours = ["mpeg", str(clouds[0]), str(clouds[1]), "--sampling", "mesh", "--json"]
    assert main([*ours, "--output-model-ref", str(tmp_path / "o.ply")]) == 0
    d = json.loads(capsys.readouterr().out)
    assert f"{d['d2_psnr']:.9g}" == "66.3524367" and f"{d['dis_to_ref']['d2_psnr']:.9g}" == "66.5918393"
    assert f"{d['d1_psnr']:.9g}" == "44.9699836"
    assert (tmp_path / "o.ply").read_bytes() == clouds[0].read_bytes()


def test_refusals(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = MM_TESTS / "plane.obj"
    assert main(["mpeg", str(a), str(a), "--mode", "equ", "--output-model-ref", str(tmp_path / "x.txt")]) == 2
    assert "must end with .ply or .obj" in capsys.readouterr().err
    (tmp_path / "mine.ply").write_text("mine")
    assert main(["mpeg", str(a), str(a), "--mode", "equ", "--output-model-ref", str(tmp_path / "mine.ply")]) == 2
    assert "already exists" in capsys.readouterr().err and (tmp_path / "mine.ply").read_text() == "mine"
    assert main(["mpeg", str(a), str(a), "--mode", "equ", "--output-model-ref", str(a)]) == 2
    capsys.readouterr()


_OPTIONS = ["--radius-curvature", "0.01", "--threshold-knn-search", "10", "--radius-factor", "1.5"]
PCQM_RUNS = [
    ["plane.obj", "plane_qp8.obj"],
    ["triangles_qp8.obj", "triangles.obj", "--dis-texture", "plane_10_10.png", *_OPTIONS],
]
"""The runs of the stored ``outputs/pcqm.csv`` (mm run in tests/data/mmetric on these relative names)."""


def test_pcqm_csv_rows(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """--output-csv in pcqm mode: mm's header and rows (the options, the float32 score, its PSNR). It was refused."""
    monkeypatch.chdir(MM_TESTS)
    for run in PCQM_RUNS:
        assert main(["mpeg", *run, "--mode", "pcqm", "--output-csv", str(tmp_path / "p.csv")]) == 0
    assert (tmp_path / "p.csv").read_bytes() == (OUT / "pcqm.csv").read_bytes()
    (tmp_path / "other.csv").write_text("p_inputModelA;p_inputModelB\n")
    assert main(["mpeg", *PCQM_RUNS[0], "--mode", "pcqm", "--output-csv", str(tmp_path / "other.csv")]) == 1
    assert "not this mode's header" in capsys.readouterr().err


def test_grid_cloud_as_obj(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Grid mode's clouds are mm sample's files: as OBJ, mm sample's (no mtllib header, bilinear colours / 255)."""
    a = MM_TESTS / "plane.obj"
    assert main(["mpeg", str(a), str(a), "--grid-size", "8", "--output-model-ref", str(tmp_path / "g.obj")]) == 0
    assert (tmp_path / "g.obj").read_bytes() == (OUT / "grid8_plane.obj").read_bytes()
    capsys.readouterr()


SEAM = "v 0 0 0\nv 4 0 0\nv 0 4 0\nv 4 4 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 0.5 0.5\nvt 0.2 0.2\nvt 1 1\n"
SEAM += "f 1/1 2/2 3/3\nf 2/4 4/6 3/5\n"
"""A square of two triangles whose shared corners have other UVs in each (a seam), no texture map."""


@pytest.mark.parametrize("mode", ["pcc", "pcqm"])
def test_uv_seam_without_map(tmp_path: Path, mode: str, capsys: pytest.CaptureFixture[str]) -> None:
    """UVs without a map key mmetric's reorder and point builder: the seam's points are kept once per UV (30
    points, mm's file; the UVs were ignored, 25). As OBJ the cloud has its UVs: mm v1.1.7 aborts writing it
    (std::bad_alloc / length_error, a material of index -1); the library writes them as mm sample does."""
    (tmp_path / "seam.obj").write_text(SEAM)
    extra = ("--sampling", "mesh") if mode == "pcc" else ()
    a = tmp_path / "seam.obj"
    assert _run(tmp_path, mode, a, a, "c.ply", "c.obj", *extra) == 0
    assert (tmp_path / "c.ply").read_bytes() == (OUT / "pcc_seam.ply").read_bytes()
    lines = (tmp_path / "c.obj").read_text().splitlines()
    assert [x.split()[0] for x in lines[1:] if x].count("vt") == 30 and lines[-1] == "usemtl material0000"
    capsys.readouterr()
