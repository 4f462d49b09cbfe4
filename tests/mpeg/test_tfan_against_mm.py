"""``tfan_equality`` against the ``mm`` binary's ``compare --mode eqTFAN`` (skipped where it is absent): every ordered
pair of mmetric's test meshes, shuffled meshes (renamed vertices, UVs and faces, rotated corners) and their altered
copies, a demo frame, each with and without ``--eqTFAN_earlyReturn``."""

from __future__ import annotations

import itertools
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg import TfanMesh, load_tfan_mesh, tfan_equality

T = MM_TESTS
_needs_mm = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
_LABELS = ("meshes are", " meshes are", "the geometry", "the texture", "Position differences", "UV coords differences")
_LABELS += ("Colors differences", "Normals differences")


def _mm(a: Path, b: Path, early: bool) -> str:
    args = [str(MM), "compare", "--mode", "eqTFAN", "--inputModelA", str(a), "--inputModelB", str(b)]
    out = subprocess.run(
        [*args, f"--eqTFAN_earlyReturn={'true' if early else 'false'}"], capture_output=True, text=True, timeout=300
    ).stdout
    lines = out[out.index("eqTFAN_Epsilon") :].splitlines()[1:]
    return "\n".join(line for line in lines if line.startswith(_LABELS))


def _agree(a: Path, b: Path) -> list[str]:
    ma, mb = load_tfan_mesh(a), load_tfan_mesh(b)
    got = []
    for early in (True, False):
        ours = tfan_equality(ma, mb, early_return=early)
        assert ours == _mm(a, b, early), (a.name, b.name, early)
        got.append(ours)
    return got


@_needs_mm
def test_mmetric_test_meshes() -> None:
    names = sorted(p.stem for p in T.glob("*.obj") if p.stem != "plane_multi_map")
    verdicts = set()
    for a, b in itertools.product(names, names):
        verdicts |= {r.splitlines()[-1].split(",")[0] for r in _agree(T / f"{a}.obj", T / f"{b}.obj")}
    assert {" meshes are equal", "meshes are not equal", "Normals differences: 0"} <= verdicts


def _write(
    v: np.ndarray, f: np.ndarray, path: Path, uv: np.ndarray | None = None, fuv: np.ndarray | None = None
) -> Path:
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v]
    if uv is not None and fuv is not None:
        lines += [f"vt {x:.9g} {y:.9g}" for x, y in uv]
        lines += [
            f"f {a + 1}/{p + 1} {b + 1}/{q + 1} {c + 1}/{r + 1}" for (a, b, c), (p, q, r) in zip(f, fuv, strict=True)
        ]
    else:
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    path.write_text("\n".join(lines) + "\n")
    return path


def _shuffle(
    v: np.ndarray, f: np.ndarray, rng: np.random.Generator, uv: np.ndarray | None = None, fuv: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Vertices, UVs and faces renamed, each face's corners rotated (the same rotation for its UV corners)."""
    vp, fp = rng.permutation(len(v)), rng.permutation(len(f))
    shift = rng.integers(0, 3, len(f))
    rot = lambda t: np.stack([np.roll(r, int(s)) for r, s in zip(t, shift, strict=True)])  # noqa: E731
    g = rot(np.argsort(vp)[f[fp]])
    if uv is None or fuv is None:
        return v[vp], g, None, None
    up = rng.permutation(len(uv))
    return v[vp], g, uv[up], rot(np.argsort(up)[fuv[fp]])


@_needs_mm
def test_shuffled_capsule(tmp_path: Path) -> None:
    cap = trimesh.creation.capsule(height=1.3, radius=0.45, count=[16, 16])
    v, f = np.asarray(cap.vertices, np.float32), np.asarray(cap.faces)
    rng = np.random.default_rng(1)
    a = _write(v, f, tmp_path / "a.obj")
    v2, g, _, _ = _shuffle(v, f, rng)
    assert _agree(a, _write(v2, g, tmp_path / "b.obj"))[0].endswith(" meshes are equal")
    flipped, moved, repeated = g.copy(), v2.copy(), g.copy()
    flipped[5] = flipped[5][::-1]  # mmetric's TFAN does not see one reversed face: its verdict is kept
    moved[7] += 0.01
    repeated[3] = g[10]
    _agree(a, _write(v2, flipped, tmp_path / "c.obj"))
    assert "13 different triangles" in _agree(a, _write(moved, g, tmp_path / "d.obj"))[1]
    _agree(a, _write(v2, repeated, tmp_path / "e.obj"))


@_needs_mm
def test_shuffled_textured_grid(tmp_path: Path) -> None:
    n = 6
    xs, ys = np.meshgrid(np.arange(n), np.arange(n))
    v = np.stack([xs.ravel(), ys.ravel(), np.zeros(n * n)], 1).astype(np.float32)
    f = np.array([t for i in range(n - 1) for j in range(n - 1) for t in _quad(i * n + j, n)])
    uv = (v[:, :2] / (n - 1)).astype(np.float32)
    a = _write(v, f, tmp_path / "a.obj", uv, f)
    v2, g, u2, gu = _shuffle(v, f, np.random.default_rng(2), uv, f)
    assert u2 is not None and gu is not None
    assert _agree(a, _write(v2, g, tmp_path / "b.obj", u2, gu))[0].endswith(" meshes are equal")
    gu2 = gu.copy()
    gu2[0], gu2[7] = gu[7], gu[0]  # two faces' UV triangles exchanged: a renaming, still equal (as mm says)
    assert _agree(a, _write(v2, g, tmp_path / "c.obj", u2, gu2))[0].endswith(" meshes are equal")
    gu3 = gu.copy()
    gu3[0, 0] = gu[9, 0] if gu[9, 0] not in gu[0] else gu[9, 1]  # a corner takes another face's UV
    got = _agree(a, _write(v2, g, tmp_path / "d.obj", u2, gu3))
    # a vertex now in more UV triangles than any of A's: mmetric's "maxV2T" test fails before any fan is built
    assert got[0].splitlines()[1:3] == [
        "meshes are not equal, maxV2TA_ != maxV2TB_ ",
        "meshes are not equal, 0 different triangles",
    ]


def _quad(p: int, n: int) -> list[list[int]]:
    return [[p, p + 1, p + n], [p + 1, p + n + 1, p + n]]


@_needs_mm
def test_demo_frames(tmp_path: Path) -> None:
    from torchmeshmetric.data import demo_sequence

    frames = demo_sequence(2, resolution=48).frames
    v, f = frames[0].verts.float().numpy(), frames[0].faces.numpy()
    a = _write(v, f, tmp_path / "a.obj")
    v2, g, _, _ = _shuffle(v, f, np.random.default_rng(3))
    assert _agree(a, _write(v2, g, tmp_path / "b.obj"))[0].endswith(" meshes are equal")
    _agree(a, _write(frames[1].verts.float().numpy(), frames[1].faces.numpy(), tmp_path / "c.obj"))


def test_library_and_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
    a = TfanMesh(v, np.array([[0, 1, 2], [1, 3, 2]]))
    assert tfan_equality(a, TfanMesh(v, np.array([[0, 1, 2]]))) == (
        "meshes are not equal, number of triangles are different 2 vs 1"
    )
    moved = v.copy()
    moved[3, 2] = 0.5
    assert tfan_equality(a, TfanMesh(moved, a.triangles)).splitlines()[:2] == [
        "the geometry connectivity of meshes is not equal, early return.",
        "the texture connectivity of meshes is equal",
    ]
    pa, pb = (
        _write(v, a.triangles, tmp_path / "a.obj"),
        _write(v[[3, 2, 1, 0]], np.array([[3, 2, 1], [2, 0, 1]]), tmp_path / "b.obj"),
    )
    assert main(["mpeg", str(pa), str(pb), "--mode", "eqTFAN"]) == 0
    assert capsys.readouterr().out.endswith(" meshes are equal\n")
    pc = _write(moved, a.triangles, tmp_path / "c.obj")
    assert main(["mpeg", str(pa), str(pc), "--mode", "eqTFAN", "--all-differences"]) == 1
    assert "meshes are not equal, 1 different triangles" in capsys.readouterr().out
