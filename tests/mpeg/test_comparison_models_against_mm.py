"""``--output-model-ref/dis`` against the files ``mm compare --outputModelA/B`` writes (skipped where ``mm`` is absent).

equ, eqTFAN and topo modes on mmetric's test meshes (the empty models mm writes there) and on seeded point clouds
with signed zeros (their sorted positions, ties placed by mm's ``std::sort``); pcc (mesh sampling) and pcqm clouds
as OBJ and PLY, from meshes and from PLY point clouds. Byte for byte.
"""

from __future__ import annotations

import random
import subprocess
from pathlib import Path

import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.cli import main

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

T = MM_TESTS


def _both(tmp: Path, mode: str, a: Path, b: Path, suffixes: tuple[str, str], mm: list[str], ours: list[str]) -> None:
    """Both tools write A and B; the four files compared byte for byte."""
    mine = [tmp / f"oA{suffixes[0]}", tmp / f"oB{suffixes[1]}"]
    theirs = [tmp / f"mA{suffixes[0]}", tmp / f"mB{suffixes[1]}"]
    for p in (*mine, *theirs):
        p.unlink(missing_ok=True)
    args = [str(MM), "compare", "--mode", mode, "--inputModelA", str(a), "--inputModelB", str(b), *mm]
    args += ["--outputModelA", str(theirs[0]), "--outputModelB", str(theirs[1])]
    subprocess.run(args, capture_output=True, timeout=300, check=True, cwd=tmp)  # pcqm writes features_extracted.csv
    rc = main(["mpeg", str(a), str(b), "--mode", mode, "--output-model-ref", str(mine[0]),
               "--output-model-dis", str(mine[1]), *ours])  # fmt: skip
    assert rc in (0, 1)
    for o, m in zip(mine, theirs, strict=True):
        assert o.read_bytes() == m.read_bytes(), (mode, a.name, b.name, o.name)


MESHES = ["plane", "plane_qp8", "sphere", "triangles", "pyramid", "plane_irregular", "testA_non-manifold"]


@pytest.mark.parametrize("mode", ["equ", "eqTFAN"])
def test_meshes(tmp_path: Path, mode: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Meshes (equal, unequal, different triangle counts): the models mm leaves empty, with the OBJ's mtllib lines."""
    for k, (a, b) in enumerate(zip(MESHES, MESHES[1:] + MESHES[:1], strict=True)):
        suffixes = (".obj", ".ply") if k % 2 else (".ply", ".obj")
        _both(tmp_path, mode, T / f"{a}.obj", T / f"{a}.obj", suffixes, [], [])
        _both(tmp_path, mode, T / f"{a}.obj", T / f"{b}.obj", suffixes[::-1], [], [])
    capsys.readouterr()


def test_topology(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    faces, verts = tmp_path / "f.txt", tmp_path / "v.txt"
    faces.write_text("0 0\n1 1\n2 2\n3 3\n")
    verts.write_text("0 0\n1 3\n2 2\n3 1\n4 4\n")
    mm = ["--faceMapFile", str(faces), "--vertexMapFile", str(verts)]
    ours = ["--face-map", str(faces), "--vertex-map", str(verts)]
    for b in ("plane_shifted", "plane_reorder"):  # matching, not matching
        _both(tmp_path, "topo", T / "plane.obj", T / f"{b}.obj", (".obj", ".ply"), mm, ours)
        _both(tmp_path, "topo", T / f"{b}.obj", T / "plane.obj", (".ply", ".obj"), mm, ours)
    capsys.readouterr()


def _cloud(path: Path, seed: int, n: int) -> None:
    """A cloud of few distinct coordinates, signed zeros among them (ties std::sort places), as OBJ or ASCII PLY."""
    r = random.Random(seed)
    values = ["0", "-0", "1", "-2", "0.5", "3.25e-3"]
    rows = [" ".join(r.choice(values) for _ in range(3)) for _ in range(n)]
    if path.suffix == ".obj":
        path.write_text("".join(f"v {row}\n" for row in rows))
    else:
        head = f"ply\nformat ascii 1.0\nelement vertex {n}\n" + "".join(f"property float {c}\n" for c in "xyz")
        path.write_text(head + "end_header\n" + "".join(f"{row}\n" for row in rows))


@pytest.mark.parametrize("mode", ["equ", "eqTFAN"])
def test_point_clouds(tmp_path: Path, mode: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Sorted positions, ties of -0 and 0 placed as mm's std::sort places them (insertion sort up to 16 points,
    introsort beyond), equal and unequal clouds, both formats."""
    for seed, n in enumerate((5, 16, 17, 40, 200, 1000, 3000)):
        a, b = tmp_path / "a.obj", tmp_path / "b.ply"
        _cloud(a, seed, n)
        _cloud(b, seed if seed % 2 else seed + 100, n)
        _both(tmp_path, mode, a, b, (".ply", ".obj") if seed % 2 else (".obj", ".ply"), [], [])
    capsys.readouterr()


def test_clouds_past_one_block(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Clouds longer than a block of the row formatter (65,536 rows): the blocks join to mm's file, PLY and OBJ.

    Random float32 coordinates of every magnitude from 1e-7 to 1e7 (nine digits each), signed zeros among them.
    """
    import numpy as np

    from torchmeshmetric.mpeg.core._text_rows import BLOCK_ROWS

    rng = np.random.default_rng(12)
    n = BLOCK_ROWS + 1000
    p = (rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-7, 8, (n, 3))).astype(np.float32)
    p[rng.random((n, 3)) < 0.01] = np.float32(-0.0)
    head = f"ply\nformat ascii 1.0\nelement vertex {n}\n" + "".join(f"property float {c}\n" for c in "xyz")
    q = p[::-1].copy()
    q[::5] *= np.float32(1.5)  # an unequal pair: each file is its own cloud sorted
    for name, cloud in (("a.ply", p), ("b.ply", q)):
        with open(tmp_path / name, "w") as fh:
            fh.write(head + "end_header\n")
            np.savetxt(fh, cloud, fmt="%.9g")
    _both(tmp_path, "equ", tmp_path / "a.ply", tmp_path / "b.ply", (".ply", ".obj"), [], [])
    capsys.readouterr()


@pytest.mark.parametrize("mode", ["pcc", "pcqm"])
def test_sampled_clouds(tmp_path: Path, mode: str, capsys: pytest.CaptureFixture[str]) -> None:
    """pcc (mesh sampling) and pcqm: the clouds of meshes (textured: colours; not: normals only) as OBJ and PLY.

    ``plane_qp8`` is left out of the OBJ cases: its cloud carries UVs (``vt`` lines and no map), and mm v1.1.7
    aborts writing it as OBJ (``std::bad_alloc``: its writer names the material of index -1).
    """
    ours = ["--sampling", "mesh"] if mode == "pcc" else []
    pairs = [("plane", "sphere"), ("sphere_qp8", "plane_irregular"), ("triangles", "pyramid")]
    for a, b in pairs:
        _both(tmp_path, mode, T / f"{a}.obj", T / f"{b}.obj", (".obj", ".obj"), [], ours)
    _both(tmp_path, mode, T / "plane_qp8.obj", T / "plane.obj", (".ply", ".obj"), [], ours)
    capsys.readouterr()


@pytest.mark.parametrize("mode", ["pcc", "pcqm"])
def test_point_cloud_inputs(tmp_path: Path, mode: str, capsys: pytest.CaptureFixture[str]) -> None:
    """PLY point clouds (mm sample's, with normals; with colours) pass through: mm writes them back, normals too."""
    clouds = []
    for name, extra in (("sphere", []), ("plane", ["--texture", str(T / "plane_10_10.png")])):
        clouds.append(tmp_path / f"{name}.ply")
        assert main(["sample", str(T / f"{name}.obj"), str(clouds[-1]), "--resolution", "16", *extra]) == 0
    ours = ["--sampling", "mesh"] if mode == "pcc" else []
    _both(tmp_path, mode, clouds[0], clouds[1], (".obj", ".ply"), [], ours)
    _both(tmp_path, mode, clouds[1], clouds[0], (".obj", ".ply"), [], ours)
    capsys.readouterr()


def test_pcqm_csv(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """pcqm --outputCsv, appended twice, absolute names: mm's file byte for byte."""
    runs = [
        (["plane.obj", "plane_qp8.obj"], [], []),
        (["sphere.obj", "sphere_qp8.obj"], ["--radiusCurvature", "0.002"], ["--radius-curvature", "0.002"]),
        (["triangles_qp8.obj", "triangles.obj"], ["--inputMapB", str(T / "plane_10_10.png")],
         ["--dis-texture", str(T / "plane_10_10.png")]),
    ]  # fmt: skip
    for _ in range(2):
        for (a, b), mm, ours in runs:
            args = [str(MM), "compare", "--mode", "pcqm", "--inputModelA", str(T / a), "--inputModelB", str(T / b)]
            subprocess.run([*args, *mm, "--outputCsv", str(tmp_path / "mm.csv")], capture_output=True, cwd=tmp_path)
            mine = ["mpeg", str(T / a), str(T / b), "--mode", "pcqm", *ours, "--output-csv", str(tmp_path / "o.csv")]
            assert main(mine) == 0
    assert (tmp_path / "o.csv").read_bytes() == (tmp_path / "mm.csv").read_bytes()
    capsys.readouterr()


def test_grid_clouds_as_obj(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Grid mode's OBJ clouds are ``mm sample --mode grid ... -o X.obj``'s files (no header, float colours / 255)."""
    lo, hi = "-5 -5 0", "5 5 0"  # plane.obj's box
    ours = ["mpeg", str(T / "plane.obj"), str(T / "sphere_qp8.obj"), "--grid-size", "32", "--box", lo, hi]
    ours += ["--output-model-ref", str(tmp_path / "oA.obj"), "--output-model-dis", str(tmp_path / "oB.obj")]
    assert main(ours) == 0
    for name, out in (("plane", "oA.obj"), ("sphere_qp8", "oB.obj")):
        args = [str(MM), "sample", "--mode", "grid", "--gridSize", "32", "--useNormal", "--bilinear", "--minPos", lo]
        args += ["--maxPos", hi, "-i", str(T / f"{name}.obj"), "-o", str(tmp_path / "m.obj"), "--hideProgress"]
        subprocess.run(args, capture_output=True, timeout=300, check=True, cwd=tmp_path)
        assert (tmp_path / out).read_bytes() == (tmp_path / "m.obj").read_bytes(), name
    capsys.readouterr()


@pytest.mark.parametrize("mode", ["pcc", "pcqm"])
def test_uv_seam_without_map(tmp_path: Path, mode: str, capsys: pytest.CaptureFixture[str]) -> None:
    """A mesh with UV seams and no map: mm keeps a point per UV; its PLY cloud (its OBJ aborts mm)."""
    from tests.mpeg.test_comparison_models import SEAM

    (tmp_path / "seam.obj").write_text(SEAM)
    (tmp_path / "flat.obj").write_text(SEAM.replace("v 4 4 0", "v 4 4 1"))
    ours = ["--sampling", "mesh"] if mode == "pcc" else []
    _both(tmp_path, mode, tmp_path / "seam.obj", tmp_path / "flat.obj", (".ply", ".ply"), [], ours)
    _both(tmp_path, mode, T / "plane_qp8.obj", T / "sphere.obj", (".ply", ".ply"), [], ours)
    capsys.readouterr()
