"""``--output-model-ref/dis`` in equ, eqTFAN, topo and pcqm modes and as OBJ in pcc mode, against files ``mm`` wrote.

The files in ``tests/data/mmetric/outputs`` are ``mm`` v1.1.7's (README there), so these run in every clone; the
same cases against the binary itself are in ``test_comparison_models_against_mm.py``.
"""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from tests.mpeg.conftest import MM_TESTS
from torchmeshmetric import native
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg.comparison.point_order import (
    _introsort,
    _tie_ranks,
    lexicographic_order,
    mmetric_point_order,
)

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


def test_lexicographic_order_is_lexsort() -> None:
    """The two integer sorts give ``np.lexsort((z, y, x))``'s order of the keys: ties in input order, -0 as 0, every
    float magnitude and sign, infinities, subnormals, runs of equal x or (x, y), and no point or one."""
    rng = np.random.default_rng(4)
    few = np.array([0.0, -0.0, 1.0, -1.0, 1e-45, -1e-45, 3.4e38, -3.4e38, np.inf, -np.inf, 0.5], np.float32)
    clouds = [rng.choice(few, (n, 3)) for n in (0, 1, 2, 17, 5000)]
    clouds.append(rng.integers(0, 2**32, (20000, 3), dtype=np.uint64).astype(np.uint32).view(np.float32))
    clouds[-1][np.isnan(clouds[-1])] = np.float32(7.0)  # no NaN: C's < orders none
    clouds.append(np.stack([rng.choice(few, 20000), rng.normal(size=20000), rng.normal(size=20000)], 1))
    for p in clouds:
        keys, order = lexicographic_order(p)
        expected = np.lexsort((keys[:, 2], keys[:, 1], keys[:, 0]))
        assert np.array_equal(order, expected)
        assert not np.signbit(keys[keys == 0]).any()


# clouds whose ties mix -0 and 0, and the positions mm compare --mode equ --outputModelA wrote sorted: cloud_a (40
# points), a McIlroy adversary of 1000 points (x = killer rank // 2; libstdc++ reaches its heapsort, one call over 964
# points, counted in an instrumented copy of the replay) and 500 points of three x values (long runs of ties)
MM_SORTS = [
    ("cloud_a.obj", "sorted_a.ply"),
    ("killer_cloud.obj", "killer_sorted.ply"),
    ("ties_cloud.obj", "ties_sorted.ply"),
]


def _mm_sorted_rows(cloud: str, sorted_file: str) -> tuple[np.ndarray, np.ndarray, list[str]]:
    from torchmeshmetric.mpeg.comparison.equality import load_equality_model

    p = load_equality_model(OUT / cloud).positions
    keys, order = lexicographic_order(p)
    rank = _tie_ranks(p, keys, order)
    assert rank is not None
    return p, rank, [line.rstrip() for line in (OUT / sorted_file).read_text().splitlines()[8:]]


@pytest.mark.parametrize(("cloud", "sorted_file"), MM_SORTS)
def test_introsort_tie_order(cloud: str, sorted_file: str) -> None:
    """The replay's order of ties is mm's (the -0 / 0 pattern of its file), in Python and in C++; a stable sort's is
    not. (This test checked only that the output was sorted, blind to the order of ties.)"""
    p, rank, mm_rows = _mm_sorted_rows(cloud, sorted_file)
    stable = lexicographic_order(p)[1]
    orders = {"python": np.asarray(_introsort(rank.tolist())), "native": mmetric_point_order(p), "stable": stable}
    rows = {k: [" ".join(f"{v:.9g}" for v in r) for r in p[o].astype(np.float64).tolist()] for k, o in orders.items()}
    assert rows["python"] == mm_rows and rows["native"] == mm_rows
    assert rows["stable"] != mm_rows


def test_native_introsort_is_the_reference() -> None:
    """The C++ replay leaves the Python reference's permutation on ranks of every shape: many ties, sorted, reversed,
    organ pipe, all equal, the McIlroy adversary (heapsort) and its ranks // 7, tiny, 16 / 17 elements."""
    ext = native.load("pcc")
    rng = np.random.default_rng(0)
    killer = _mm_sorted_rows("killer_cloud.obj", "killer_sorted.ply")[1]
    cases = [rng.integers(0, 3, 500), np.arange(300), np.arange(300)[::-1], rng.integers(0, 10**6, 1000),
             np.minimum(np.arange(2000), 2000 - np.arange(2000)), np.zeros(100, np.int64), killer, killer // 7,
             np.array([1, 0]), np.array([0]), np.array([], np.int64), rng.integers(0, 4, 16),
             rng.integers(0, 4, 17)]  # fmt: skip
    for rank in cases:
        rank = np.ascontiguousarray(rank, np.int64)
        expected = _introsort(rank.tolist())
        assert ext.introsort_permutation(torch.from_numpy(rank)).tolist() == expected, rank[:20]
        assert np.all(np.diff(rank[expected]) >= 0)


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


CSEAM = SEAM.replace("v 0 0 0\n", "v 0 0 0 1 0 0\n").replace("v 4 0 0\n", "v 4 0 0 0 1 0\n")
CSEAM = CSEAM.replace("v 0 4 0\n", "v 0 4 0 0 0 1\n").replace("v 4 4 0\n", "v 4 4 0 1 1 1\n")
""":data:`SEAM` with per-vertex colours (still no map); the distorted copy has its fourth vertex black."""


def test_coloured_uv_seam_without_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Vertex colours and UVs without a map: the points keep their colours (mm keys on the UVs and keeps the colours;
    the colours were dropped, no colour rows and PCQM 0). mm's figures: ``c[0],PSNRF`` 9.03480018, PCQM 0.210767856,
    and its PLY (``pcc_cseam.ply``, with ``red green blue``)."""
    a, b = tmp_path / "cs_ref.obj", tmp_path / "cs_dis.obj"
    a.write_text(CSEAM)
    b.write_text(CSEAM.replace("v 4 4 0 1 1 1\n", "v 4 4 0 0 0 0\n"))
    assert (
        main(
            ["mpeg", str(a), str(b), "--sampling", "mesh", "--peak", "1", "--output-model-ref", str(tmp_path / "c.ply")]
        )
        == 0
    )
    rows = {line.split()[0]: line.split()[1:] for line in capsys.readouterr().out.splitlines() if line.strip()}
    assert rows["y_psnr"][0] == "9.03480018"
    assert (tmp_path / "c.ply").read_bytes() == (OUT / "pcc_cseam.ply").read_bytes()
    assert main(["mpeg", str(a), str(b), "--mode", "pcqm"]) == 0
    assert "PCQM value is : 0.210767856" in capsys.readouterr().out


def _seamed_frames(tmp: Path, colours: bool) -> tuple[Path, Path]:
    """Demo frames 0 and 1 (resolution 32) with random UVs, a seam at every face's first corner, no map; with
    ``colours`` also random vertex colours (the review's ``mkseam.py``, seeds 3 and 5)."""
    from torchmeshmetric.data import demo_sequence, save_mesh

    seq = demo_sequence(num_frames=2, resolution=32)
    rng, crng, paths = np.random.default_rng(3), np.random.default_rng(5), []
    for i in (0, 1):
        save_mesh(seq.frames[i], tmp / "frame.obj", overwrite=True)
        lines = (tmp / "frame.obj").read_text().splitlines()
        vs, fs = [x for x in lines if x.startswith("v ")], [x for x in lines if x.startswith("f ")]
        out = vs + [f"vt {u:.6g} {v:.6g}" for u, v in rng.random((len(vs), 2))]
        rows = []
        for k, face in enumerate(fs):
            a, b, c = (int(x.split("/")[0]) for x in face.split()[1:])
            out.append(f"vt {rng.random():.6g} {rng.random():.6g}")
            rows.append(f"f {a}/{len(vs) + k + 1} {b}/{b} {c}/{c}")
        paths.append(tmp / f"seam{i}.obj")
        paths[-1].write_text("\n".join(out + rows) + "\n")
    if colours:  # a second pass, as the review made them: "v x y z" + " r g b"
        for path in paths:
            text = [x + " {:.4f} {:.4f} {:.4f}".format(*crng.random(3)) if x.startswith("v ") else x
                    for x in path.read_text().splitlines()]  # fmt: skip
            path.write_text("\n".join(text) + "\n")
    return paths[0], paths[1]


def test_seamed_frames_figures(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A UV seam at every face of two demo frames: the UV keying moved D2's MSE to mm's ``mseF (p2plane)``
    0.000177506416 (0.000177506417 before, the seam's copies merged); with vertex colours PCQM is mm's 0.383744443
    (0 while the colours were dropped)."""
    a, b = _seamed_frames(tmp_path, colours=False)
    assert main(["mpeg", str(a), str(b), "--sampling", "mesh", "--peak", "1"]) == 0
    rows = {line.split()[0]: line.split()[1:] for line in capsys.readouterr().out.splitlines() if line.strip()}
    assert rows["d2_mse"][0] == "0.000177506416"
    a, b = _seamed_frames(tmp_path, colours=True)
    assert main(["mpeg", str(a), str(b), "--mode", "pcqm"]) == 0
    assert "PCQM value is : 0.383744443" in capsys.readouterr().out


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


class _ClosedStdout(io.StringIO):
    """A stdout whose reader went away (``... | head -1``): every write raises BrokenPipeError."""

    def write(self, text: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")


@pytest.mark.parametrize("mode", ["equ", "eqTFAN", "pcqm", "ibsm", "topo"])
def test_files_written_before_printing(tmp_path: Path, mode: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """With stdout closed the files asked for are still written, as in pcc mode (these modes printed first, so the
    BrokenPipeError ended them with nothing written, exit status 1 or 2 and no message); the exit status stays
    non-zero, as SIGPIPE's (mm, which prints first, dies of it with no file)."""
    plane = MM_TESTS / "plane.obj"
    extra: list[str] = []
    if mode == "topo":
        (tmp_path / "f.txt").write_text("".join(f"{i} {i}\n" for i in range(2)))
        (tmp_path / "v.txt").write_text("".join(f"{i} {i}\n" for i in range(4)))
        extra = ["--face-map", str(tmp_path / "f.txt"), "--vertex-map", str(tmp_path / "v.txt")]
    if mode in ("pcqm", "ibsm"):
        extra = ["--output-csv", str(tmp_path / "s.csv")]
    monkeypatch.setattr(sys, "stdout", _ClosedStdout())
    assert _run(tmp_path, mode, plane, plane, "a.ply", "b.obj", *extra) != 0
    assert (tmp_path / "a.ply").is_file() and (tmp_path / "b.obj").is_file()
    assert mode not in ("pcqm", "ibsm") or (tmp_path / "s.csv").is_file()


def _normal_clouds(tmp: Path) -> tuple[Path, Path, Path]:
    """200 seeded points with unit normals: REF with its normals declared ``nz ny nx`` (values by name), the same
    REF declared ``nx ny nz``, and DIS (REF shifted by 0.01, other normals, ``nx ny nz``)."""
    rng = np.random.default_rng(7)
    p = rng.random((200, 3))
    n = rng.normal(size=(200, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    m = rng.normal(size=(200, 3))
    m /= np.linalg.norm(m, axis=1, keepdims=True)

    def ply(path: Path, pos: np.ndarray, nrm: np.ndarray, names: str) -> Path:
        head = "ply\nformat ascii 1.0\nelement vertex 200\n" + "".join(f"property float {c}\n" for c in "xyz")
        head += "".join(f"property float {c}\n" for c in names.split()) + "end_header\n"
        cols = [nrm[:, "xyz".index(c[1])] for c in names.split()]
        rows = zip(pos, np.stack(cols, 1), strict=True)
        body = "".join(" ".join(f"{v:.6g}" for v in (*a, *b)) + "\n" for a, b in rows)
        path.write_text(head + body)
        return path

    return (ply(tmp / "zyx.ply", p, n, "nz ny nx"), ply(tmp / "xyz.ply", p, n, "nx ny nz"),
            ply(tmp / "dis.ply", p + 0.01, m, "nx ny nz"))  # fmt: skip


def test_point_cloud_normals_read_by_name(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Normals declared ``nz ny nx`` are read by name, as positions are (docs/mpeg.md): the figures of the same cloud
    declared ``nx ny nz``, which are mm's there. mm v1.1.7 takes the normal columns in their declared order whatever
    their names (a divergence kept: the PLY format's meaning). Measured on these clouds: DIS->REF D2 PSNR
    (REF's normals) is mm's 44.5637053 on the nx-ny-nz file and the library's on both, where mm prints 44.5781654 on
    the nz-ny-nx one; REF->DIS (DIS's normals) 44.5772255 everywhere."""
    zyx, xyz, dis = _normal_clouds(tmp_path)
    out = []
    for ref in (zyx, xyz):
        assert main(["mpeg", str(ref), str(dis), "--sampling", "mesh", "--peak", "1"]) == 0
        out.append(capsys.readouterr().out)
    assert out[0] == out[1]
    assert [line.split() for line in out[0].splitlines() if line.startswith("d2_psnr")] == [
        ["d2_psnr", "44.5637053", "44.5772255", "44.5637053"]
    ]
