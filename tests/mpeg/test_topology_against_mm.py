"""``topology_equivalence`` against the ``mm`` binary's ``compare --mode topo`` (skipped where it is absent).

The map files of mmetric's ``test-compare-topo.sh`` are not among the copied test meshes; the test writes them (four
and five lines), and builds its own cases: a capsule and a demo frame with faces and vertices shuffled and corners
rotated, under their true maps, a wrong map, a flipped face, a map missing a line, and a decimated B.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.mpeg import TopologyMapError, load_textured_mesh, topology_equivalence

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS


def _mm(a: Path, b: Path, faces: Path, verts: Path) -> tuple[str, str]:
    """mm's verdict lines (stdout) and its error line (stderr)."""
    args = [str(MM), "compare", "--mode", "topo", "--inputModelA", str(a), "--inputModelB", str(b)]
    args += ["--faceMapFile", str(faces), "--vertexMapFile", str(verts)]
    run = subprocess.run(args, capture_output=True, text=True, timeout=120, check=True)
    # mmetric ends the triangle-count verdict without a newline: its next line follows on the same line
    out = run.stdout.replace("Time on processing", "\nTime on processing")
    keep = ("Topologies are", "modelA->", "modelB(")
    verdict = "\n".join(line for line in out.splitlines() if line.startswith(keep))
    return verdict, run.stderr.strip()


def _maps(tmp: Path, faces: np.ndarray, verts: np.ndarray, name: str = "") -> tuple[Path, Path]:
    f, v = tmp / f"faces{name}.txt", tmp / f"verts{name}.txt"
    f.write_text("".join(f"{b} {a}\n" for b, a in enumerate(faces.tolist())))
    v.write_text("".join(f"{b} {a}\n" for b, a in enumerate(verts.tolist())))
    return f, v


def _write(v: np.ndarray, f: np.ndarray, path: Path) -> Path:
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    path.write_text("\n".join(lines) + "\n")
    return path


def _agree(a: Path, b: Path, faces: Path, verts: Path) -> str:
    ours = topology_equivalence(load_textured_mesh(a), load_textured_mesh(b), faces, verts).report()
    theirs, err = _mm(a, b, faces, verts)
    assert err == ""
    assert ours == theirs
    return ours


def test_regression_script_cases(tmp_path: Path) -> None:
    """test-compare-topo.sh: plane_reorder is not orientation-preserving, plane_shifted matches."""
    (tmp_path / "f.txt").write_text("0 0\n1 1\n2 2\n3 3")  # mmetric's files end without a newline
    (tmp_path / "v.txt").write_text("0 0\n1 3\n2 2\n3 1\n4 4")
    f, v = tmp_path / "f.txt", tmp_path / "v.txt"
    got = _agree(TESTS / "plane.obj", TESTS / "plane_reorder.obj", f, v)
    assert got.startswith("Topologies are different: orientations are not preserved")
    assert _agree(TESTS / "plane.obj", TESTS / "plane_shifted.obj", f, v) == "Topologies are matching."
    assert _agree(TESTS / "plane.obj", TESTS / "sphere.obj", f, v).endswith("(A=4,B=960).")


def _shuffled_cases(v: np.ndarray, f: np.ndarray, tmp: Path, seed: int) -> None:
    """B = A with faces and vertices permuted and corners rotated; true, wrong, flipped, partial and decimated."""
    rng = np.random.default_rng(seed)
    fperm, vperm = rng.permutation(len(f)), rng.permutation(len(v))  # B's face j is A's face fperm[j]; same for v
    inv = np.argsort(vperm)  # A's vertex i is B's vertex inv[i]
    g = inv[f[fperm]]
    g = np.stack([np.roll(row, int(s)) for row, s in zip(g, rng.integers(0, 3, len(g)), strict=True)])
    a = _write(v, f, tmp / "a.obj")
    b = _write(v[vperm], g, tmp / "b.obj")
    assert _agree(a, b, *_maps(tmp, fperm, vperm, "true")) == "Topologies are matching."
    wrong = fperm.copy()
    wrong[[3, 8]] = wrong[[8, 3]]  # two faces given each other's partner
    assert "orientations are not preserved" in _agree(a, b, *_maps(tmp, wrong, vperm, "wrong"))
    vwrong = vperm.copy()
    vwrong[[0, 1]] = vwrong[[1, 0]]
    assert "orientations are not preserved" in _agree(a, b, *_maps(tmp, fperm, vwrong, "vwrong"))
    flipped = g.copy()
    flipped[len(g) // 2] = flipped[len(g) // 2, ::-1]
    c = _write(v[vperm], flipped, tmp / "c.obj")
    assert "orientations are not preserved" in _agree(a, c, *_maps(tmp, fperm, vperm, "true"))
    fpart, vpart = _maps(tmp, fperm, vperm, "part")
    fpart.write_text("".join(fpart.read_text().splitlines(keepends=True)[:-1]))
    assert _agree(a, b, fpart, vpart).endswith("face map is not bijective.")
    fpart, vpart = _maps(tmp, fperm, vperm, "vpart")
    vpart.write_text("".join(vpart.read_text().splitlines(keepends=True)[1:]))
    assert _agree(a, b, fpart, vpart).endswith("vertex map is not bijective.")
    d = _write(v[vperm], g[: len(g) * 3 // 4], tmp / "d.obj")  # a decimated B: fewer triangles
    assert "number of triangles differs" in _agree(a, d, fpart, vpart)


def test_shuffled_capsule(tmp_path: Path) -> None:
    cap = trimesh.creation.capsule(height=1.3, radius=0.45, count=[16, 16])
    _shuffled_cases(np.asarray(cap.vertices, np.float32), np.asarray(cap.faces, np.int64), tmp_path, 3)


def test_shuffled_demo_frame(tmp_path: Path) -> None:
    from torchmeshmetric.data import demo_sequence

    frame = demo_sequence(1, resolution=48).frames[0]
    _shuffled_cases(frame.verts.float().numpy(), frame.faces.numpy(), tmp_path, 11)


_BAD = [
    ("0 0\n\n1 1\n2 2\n3 3\n", "missing face number 0"),
    ("0 0\n1\n2 2\n3 3\n", "missing face number 1"),
    ("0 0\n1 -1\n2 2\n3 3\n", "face index out of range (faces[1]=18446744073709551615)"),
    ("0 0\n1.5 1\n2 2\n3 3\n", "missing face number 1"),
    ("0 0\n1 1\n1 2\n3 3\n", "modelB face 1 already associated with modelA face 1"),
    ("0 0\n1 1\n2 2\n3 3\n4 0\n", "face index out of range (faces[0]=4)"),
    ("0 0\n1 1\n2 2\n3 3\n\n", "missing face number 0"),
    ("0 0\n1 1\n2 2\n3 99999999999999999999999\n", "missing face number 1"),
]


@pytest.mark.parametrize("text,mm_error", _BAD)
def test_bad_face_map_lines(tmp_path: Path, text: str, mm_error: str) -> None:
    """Where mm prints ``Error: FILE:N ...`` (N counted from 0) the library raises naming FILE:N+1."""
    f, v = tmp_path / "f.txt", tmp_path / "v.txt"
    f.write_text(text)
    v.write_text("0 0\n1 3\n2 2\n3 1\n4 4")
    _, err = _mm(TESTS / "plane.obj", TESTS / "plane_shifted.obj", f, v)
    assert err.startswith(f"Error: {f}:") and mm_error in err
    line = int(err.split(":")[2].split()[0])
    a, b = load_textured_mesh(TESTS / "plane.obj"), load_textured_mesh(TESTS / "plane_shifted.obj")
    with pytest.raises(TopologyMapError, match=f"{f}:{line + 1}: "):
        topology_equivalence(a, b, f, v)


def test_bad_vertex_map_and_missing_file(tmp_path: Path) -> None:
    f, v = tmp_path / "f.txt", tmp_path / "v.txt"
    f.write_text("0 0\n1 1\n2 2\n3 3\n")
    v.write_text("0 0\n1 3\n2 2\n3 1\n4 4\n5 0\n")
    a, b = load_textured_mesh(TESTS / "plane.obj"), load_textured_mesh(TESTS / "plane_shifted.obj")
    _, err = _mm(TESTS / "plane.obj", TESTS / "plane_shifted.obj", f, v)
    assert err == f"Error: {v}:5 vertex index out of range (vertex[0]=5) >= (modelA.getPositionCount()=5)"
    with pytest.raises(TopologyMapError, match=f"{v}:6: vertex index 5"):
        topology_equivalence(a, b, f, v)
    _, err = _mm(TESTS / "plane.obj", TESTS / "plane_shifted.obj", tmp_path / "none.txt", v)
    assert err.startswith("Error: can't open topology face mapping file")
    with pytest.raises(TopologyMapError, match=r"none\.txt"):
        topology_equivalence(a, b, tmp_path / "none.txt", v)


def test_arrays_equal_files(tmp_path: Path) -> None:
    """Maps given as tensors decide as the files do."""
    a, b = load_textured_mesh(TESTS / "plane.obj"), load_textured_mesh(TESTS / "plane_shifted.obj")
    got = topology_equivalence(a, b, torch.arange(4), torch.tensor([0, 3, 2, 1, 4]))
    assert got.matching and got.report() == "Topologies are matching."
