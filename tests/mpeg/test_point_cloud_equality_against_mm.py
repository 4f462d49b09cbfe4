"""Models without faces (point clouds) in ``equ`` and ``eqTFAN`` against the ``mm`` binary (skipped where it is
absent): every line mm prints between its ``Epsilon = `` header and ``Time on processing``, on seeded random clouds
(permuted, moved, duplicated, dropped points, -0.0, ties) as OBJ, ASCII PLY and binary PLY, with epsilon 0, epsilons
on the boundary of the distance test and others; colours, normals and UVs (ignored); a model with faces against one
without; texture maps; float32 rounding of the text; overflowing differences; and mmetric's own
``compare_equ_pc_*`` regression cases (``sample --mode sdiv ... END compare --mode equ``, with and without
``--epsilon``)."""

from __future__ import annotations

import itertools
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from tests.mpeg.mm_compare import HEADERS, mm_block, png
from torchmeshmetric.mpeg import (
    load_equality_model,
    load_textured_mesh,
    mesh_equality,
    subdivision_sample,
    tfan_equality,
)
from torchmeshmetric.mpeg.core.model_files import point_cloud_ply_text

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

MODES = ("equ", "eqTFAN")
EPSILON_OPTION = {"equ": "--epsilon", "eqTFAN": "--eqTFAN_epsilon"}


def _write(path: Path, points: np.ndarray, form: str, *, extra: bool = False) -> Path:
    """``points`` as an OBJ (``v`` lines), an ASCII or a binary PLY; ``extra``: colours, normals (and OBJ UVs) too."""
    pts = np.asarray(points, dtype=np.float32)
    n = len(pts)
    rng = np.random.default_rng(n)
    colours = rng.integers(0, 256, (n, 3))
    normals = rng.normal(size=(n, 3)).astype(np.float32)
    if form == "obj":
        rows = [
            "v " + " ".join(f"{x:.9g}" for x in p) + ("" if not extra else " " + " ".join(f"{c / 255:.9g}" for c in k))
            for p, k in zip(pts, colours, strict=True)
        ]
        if extra:
            rows += ["vn " + " ".join(f"{x:.9g}" for x in m) for m in normals]
            rows += [f"vt {k / max(n, 1):.9g} 0.5" for k in range(n)]
        path.write_text("\n".join(rows) + "\n")
        return path
    props = ["x", "y", "z"] + (["nx", "ny", "nz"] if extra else [])
    head = ["ply", f"format {'ascii' if form == 'ascii' else 'binary_little_endian'} 1.0", f"element vertex {n}"]
    head += [f"property float {p}" for p in props]
    head += [f"property uchar {c}" for c in ("red", "green", "blue")] if extra else []
    head.append("end_header")
    fields = [(p, "<f4") for p in props] + ([(c, "u1") for c in ("red", "green", "blue")] if extra else [])
    table = np.zeros(n, dtype=fields)
    for k, c in enumerate("xyz"):
        table[c] = pts[:, k]
    if extra:
        for k, c in enumerate(("nx", "ny", "nz")):
            table[c] = normals[:, k]
        for k, c in enumerate(("red", "green", "blue")):
            table[c] = colours[:, k]
    if form == "ascii":
        body = "".join(" ".join(f"{v:.9g}" if isinstance(v, float) else str(v) for v in row.tolist()) + "\n"
                       for row in table)  # fmt: skip
        path.write_text("\n".join(head) + "\n" + body)
    else:
        path.write_bytes(("\n".join(head) + "\n").encode() + table.tobytes())
    return path


def _ours(
    mode: str, a: Path, b: Path, epsilon: float = 0.0, maps: tuple[Path | None, Path | None] = (None, None)
) -> str:
    ma, mb = load_equality_model(a, maps[0]), load_equality_model(b, maps[1])
    if mode == "equ":
        return mesh_equality(ma, mb, epsilon=epsilon).report()
    return tfan_equality(ma, mb, epsilon=epsilon).report()


def _theirs(mode: str, a: Path, b: Path, epsilon: float = 0.0, *options: str, **kw: object) -> str:
    eps = [EPSILON_OPTION[mode], f"{epsilon:.9g}"] if epsilon else []
    return mm_block(mode, a, b, *eps, *options, **kw)  # type: ignore[arg-type]


def _lengths(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The float32 distances of the sorted points (to put epsilons exactly on them)."""
    sa = a[np.lexsort(a.T[::-1])] + np.float32(0)
    sb = b[np.lexsort(b.T[::-1])] + np.float32(0)
    d = sa - sb
    return np.sqrt((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2])


def _random_pairs(seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Clouds on a coarse grid (ties, duplicates, -0.0) and a fine one; B a permutation, moved, duplicated, ..."""
    rng = np.random.default_rng(seed)
    grid = np.array([-1.0, -0.5, -0.0, 0.0, 0.25, 0.5, 1.0, 3.0], np.float32)
    pairs = []
    for n in (1, 2, 5, 12, 40):
        coarse = rng.choice(grid, size=(n, 3))
        fine = rng.normal(size=(n, 3)).astype(np.float32)
        for a in (coarse, fine):
            perm = a[rng.permutation(n)]
            moved = perm.copy()
            k = rng.integers(0, n, size=max(1, n // 4))
            moved[k] += rng.choice(np.array([1e-7, 1e-3, 0.1, 0.5], np.float32), size=(len(k), 3)) * rng.choice(
                [-1, 0, 1], size=(len(k), 3)
            ).astype(np.float32)
            signs = perm.copy()
            signs[signs == 0] = -signs[signs == 0]  # 0.0 <-> -0.0: equal for mm
            dup = np.concatenate([perm[:-1], perm[:1]]) if n > 1 else perm
            pairs += [
                (a, perm),
                (a, moved),
                (a, signs),
                (a, dup),
                (a, perm[: max(n - 1, 1)]),
                (a, rng.permutation(fine)),
            ]
    return pairs


@pytest.mark.parametrize("seed", [0, 1])
def test_random_clouds(tmp_path: Path, seed: int) -> None:
    """Every line of both modes, with epsilon 0, on the float32 distance of some moved point (``>=``: it counts), one
    float32 step above it (it does not), and 0.3; the files as OBJ, ASCII PLY and binary PLY (each side's drawn)."""
    rng = np.random.default_rng(100 + seed)
    forms = ("obj", "ascii", "binary")
    for k, (a, b) in enumerate(_random_pairs(seed)):
        fa, fb = rng.choice(forms), rng.choice(forms)
        pa = _write(tmp_path / f"a{k}.{'obj' if fa == 'obj' else 'ply'}", a, fa, extra=bool(rng.integers(2)))
        pb = _write(tmp_path / f"b{k}.{'obj' if fb == 'obj' else 'ply'}", b, fb, extra=bool(rng.integers(2)))
        epsilons = [0.0, 0.3]
        if len(a) == len(b):
            moved = _lengths(a, b)
            moved = moved[moved > 0]
            if moved.size:
                e = np.float32(rng.choice(moved))
                epsilons += [float(e), float(np.nextafter(e, np.float32(np.inf)))]  # that point counted, then not
        for mode, eps in itertools.product(MODES, epsilons):
            assert _ours(mode, pa, pb, eps) == _theirs(mode, pa, pb, eps), (k, fa, fb, mode, eps)


def test_attributes_are_ignored(tmp_path: Path) -> None:
    """Colours, normals and UVs (OBJ ``v x y z r g b``, ``vn``, ``vt``; PLY ``nx ny nz``, ``red green blue``) take
    no part: the same points with and without them are equal, in both modes, whatever the list lengths."""
    pts = np.random.default_rng(7).normal(size=(9, 3)).astype(np.float32)
    files = [_write(tmp_path / f"{f}{x}.{'obj' if f == 'obj' else 'ply'}", pts[::s], f, extra=bool(x))
             for f in ("obj", "ascii", "binary") for x, s in ((0, 1), (1, -1))]  # fmt: skip
    for a, b in itertools.product(files, files):
        for mode in MODES:
            assert _ours(mode, a, b) == _theirs(mode, a, b) == "model vertices are equals", (a.name, b.name)


def test_faces_on_one_side_only(tmp_path: Path) -> None:
    """A mesh against a point cloud: the triangle counts differ, before any point-cloud comparison (both orders,
    ``--all-differences`` / ``--earlyReturn=false`` change nothing)."""
    cloud = _write(tmp_path / "c.obj", np.eye(3, dtype=np.float32), "obj")
    mesh = tmp_path / "m.obj"
    mesh.write_text(cloud.read_text() + "f 1 2 3\n")
    for mode, (a, b) in itertools.product(MODES, ((cloud, mesh), (mesh, cloud))):
        theirs = _theirs(mode, a, b)
        assert _ours(mode, a, b) == theirs
        assert theirs.startswith("meshes are not equal, number of triangles are different")
        early = "--earlyReturn=false" if mode == "equ" else "--eqTFAN_earlyReturn=false"
        assert _theirs(mode, a, b, 0.0, early) == theirs
    assert mesh_equality(load_equality_model(cloud), load_equality_model(mesh)).report(early_return=False) == (
        "meshes are not equal, number of triangles are different 0 vs 1"
    )


def test_texture_maps(tmp_path: Path) -> None:
    """The maps' lines come first, as for meshes; the points' verdict follows."""
    pts = np.eye(3, dtype=np.float32)
    a = _write(tmp_path / "a.obj", pts, "obj")
    b = _write(tmp_path / "b.ply", pts[::-1], "binary")
    t1, t2, t3 = png(tmp_path / "t1.png", (4, 4)), png(tmp_path / "t2.png", (4, 4), 2), png(tmp_path / "t3.png", (5, 4))
    for mode, maps in itertools.product(MODES, [(t1, t1), (t1, t2), (t1, None), (None, t1), (t1, t3)]):
        assert _ours(mode, a, b, maps=maps) == _theirs(mode, a, b, maps=maps), (mode, maps)


def test_float32_reading_and_extremes(tmp_path: Path) -> None:
    """Text rounded to float32 as mm reads it (0.1 and 0.10000000149 are one float32; 0.1000001 is not), -0.0,
    subnormals (their squares underflow to a zero distance), and differences beyond float32 (an infinite distance,
    counted)."""
    cases = [
        ("v 0.1 0 0\nv 1 2 3\n", "v 1 2 3\nv 0.10000000149 -0 0\n", (0.0, 1e-9)),
        ("v 0.1 0 0\n", "v 0.1000001 0 0\n", (0.0, 1e-7, 1e-6)),
        ("v -0 -0 -0\nv 0 0 1\n", "v 0 0 1\nv 0 0 0\n", (0.0, 0.5)),
        ("v 1e-45 0 0\nv 2e-38 0 0\n", "v 0 0 0\nv 1e-38 0 0\n", (0.0, 1e-45, 1e-38, 1e-19)),
        ("v 3e38 0 0\nv 0 0 0\n", "v -3e38 0 0\nv 0 0 0\n", (0.0, 1.0, 3e38)),
        ("v 1 1 1\nv 1 1 1\nv 2 2 2\n", "v 1 1 1\nv 2 2 2\nv 2 2 2\n", (0.0, 1.0, 2.0, 1.7320508)),
    ]
    for k, (ta, tb, epsilons) in enumerate(cases):
        a, b = tmp_path / f"a{k}.obj", tmp_path / f"b{k}.obj"
        a.write_text(ta)
        b.write_text(tb)
        for mode, eps in itertools.product(MODES, epsilons):
            assert _ours(mode, a, b, eps) == _theirs(mode, a, b, eps), (ta, tb, mode, eps)


def _mm_chain(*args: str) -> str:
    """The comparison's lines of an in-memory ``mm sample ... END compare ...`` chain (mmetric's test scripts)."""
    out = subprocess.run([str(MM), *args], capture_output=True, text=True, timeout=120, check=True).stdout.splitlines()
    start = next(i for i, line in enumerate(out) if line.startswith(HEADERS["equ"]))
    stop = next(i for i, line in enumerate(out) if i > start and line.startswith("Time on processing"))
    return "\n".join(out[start + 1 : stop])


@pytest.mark.parametrize("epsilon", [0.0, 0.01])
def test_mmetric_regression_sdiv_cases(tmp_path: Path, epsilon: float) -> None:
    """mmetric's ``compare_equ_pc_plane_eps_*`` (the textured plane's sdiv samples against themselves: equal) and
    ``compare_equ_pc_plane_sphere_eps_*`` (plane against sphere: not equal): mm's in-memory chain against the
    library's ``subdivision_sample`` written as ``mm sample`` writes it, then read back."""
    eps = ["--epsilon", str(epsilon)] if epsilon else []
    plane, sphere, png_ = MM_TESTS / "plane.obj", MM_TESTS / "sphere.obj", MM_TESTS / "plane.png"
    sample = ["sample", "--mode", "sdiv", "--inputModel"]
    pair = ["--inputModelA", "ID:sampled", "--inputModelB", "ID:sampled"]
    theirs = _mm_chain(*sample, str(plane), "--inputMap", str(png_), "--outputModel", "ID:sampled", "END",
                       "compare", "--mode", "equ", *eps, *pair)  # fmt: skip
    assert theirs == "model vertices are equals"
    theirs_ps = _mm_chain(*sample, str(plane), "--outputModel", "ID:plane", "END", *sample, str(sphere),
                          "--outputModel", "ID:sphere", "END", "compare", "--mode", "equ", *eps,
                          "--inputModelA", "ID:plane", "--inputModelB", "ID:sphere")  # fmt: skip
    assert theirs_ps.startswith("model vertices are not equals")
    files = {}
    for name, mesh in (("plane_t", load_textured_mesh(plane, png_)), ("plane", load_textured_mesh(plane)),
                       ("sphere", load_textured_mesh(sphere))):  # fmt: skip
        files[name] = tmp_path / f"{name}.ply"
        files[name].write_text(point_cloud_ply_text(subdivision_sample(mesh)))
    load = {n: load_equality_model(p) for n, p in files.items()}
    assert mesh_equality(load["plane_t"], load["plane_t"], epsilon=epsilon).report() == theirs
    assert mesh_equality(load["plane"], load["sphere"], epsilon=epsilon).report() == theirs_ps
    assert tfan_equality(load["plane"], load["sphere"], epsilon=epsilon).report() == theirs_ps
    # mm on the library's files prints the same
    assert _theirs("equ", files["plane"], files["sphere"], epsilon) == theirs_ps


def _near_midpoints(e: np.float32) -> list[str]:
    """Decimals just past and just short of the float32 midpoints on either side of ``e``: float64 rounds each of them
    to the midpoint itself, so reading them through float64 picks the wrong float32 for half of them (review S)."""
    from decimal import Decimal, getcontext

    getcontext().prec = 60
    texts = []
    for other in (np.nextafter(e, np.float32(np.inf)), np.nextafter(e, np.float32(-np.inf))):
        mid = (Decimal(float(e)) + Decimal(float(other))) / 2
        for sign in (1, -1):
            texts.append(str(mid + sign * mid.copy_abs() * Decimal("1e-30")))
    assert all(np.float64(t) == np.float64(texts[0 if k < 2 else 2]) for k, t in enumerate(texts))  # the midpoints
    return texts


def test_epsilon_text_past_float32_midpoints(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--epsilon`` from decimal text, as mm reads it (the float32 nearest the text): decimals past a float32
    midpoint on either side of a distance, not float32 round-trip strings (those cannot tell double rounding apart,
    review S §3). mm prints the float32 it used; the CLI's verdict agrees with mm's."""
    from torchmeshmetric.cli import main
    from torchmeshmetric.cli.mpeg import float32

    a = _write(tmp_path / "a.obj", np.zeros((1, 3), np.float32), "obj")
    for k, x in enumerate((0.1, 1.0, 3e-3)):
        e = np.float32(x)
        b = _write(tmp_path / f"b{k}.obj", np.array([[e, 0, 0]], np.float32), "obj")
        for text in _near_midpoints(e):
            for mode in MODES:
                theirs = mm_block(mode, a, b, EPSILON_OPTION[mode], text)
                eps = float32(text)
                assert _ours(mode, a, b, eps) == theirs, (x, text, mode)
                capsys.readouterr()
                rc = main(["mpeg", "--mode", mode, str(a), str(b), "--epsilon", text])
                assert capsys.readouterr().out.strip() == theirs
                assert rc == (0 if "are equals" in theirs else 1)


def test_ascii_ply_past_float32_midpoints(tmp_path: Path) -> None:
    """ASCII PLY ``float`` coordinates read as mm reads them (the float32 nearest the text; float64 first rounded
    twice, review S §2): decimals past float32 midpoints against an OBJ of either neighbour, both modes, as a point
    cloud and as a mesh."""
    values = [np.float32(0.1), np.float32(-2.5e-3), np.float32(7.0), np.float32(1e-40)]  # 1e-40: subnormal
    texts = [t for v in values for t in _near_midpoints(v)]
    for k, text in enumerate(texts):
        ply = tmp_path / f"p{k}.ply"
        ply.write_text(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
            f"end_header\n{text} 0 0\n"
        )
        mesh = tmp_path / f"m{k}.ply"
        mesh.write_text(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            f"element face 1\nproperty list uchar int vertex_indices\nend_header\n{text} 0 0\n0 1 0\n0 0 1\n3 0 1 2\n"
        )
        x = np.float64(text)
        for j, neighbour in enumerate((np.float32(x), np.nextafter(np.float32(x), np.float32(np.sign(x) * np.inf)))):
            obj = tmp_path / f"o{k}_{j}.obj"
            obj.write_text(f"v {float(neighbour)!r} 0 0\n")
            objm = tmp_path / f"om{k}_{j}.obj"
            objm.write_text(f"v {float(neighbour)!r} 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n")
            for mode in MODES:
                assert _ours(mode, ply, obj) == _theirs(mode, ply, obj), (text, mode, j)
                assert _ours(mode, mesh, objm) == _theirs(mode, mesh, objm), (text, mode, j, "mesh")


def test_ply_positions_in_another_order_are_read_by_name(tmp_path: Path) -> None:
    """A documented divergence (review S §4, docs/mpeg.md): mm (tinyply) takes x y z in their declared order whatever
    their names; the library reads them by name. Measured here so that the docs stay true."""
    pts = np.array([[-0.0, 5, 6], [1, 2, 3], [0.1, 0.2, 0.3]], np.float32)
    ref = _write(tmp_path / "r.obj", pts, "obj")
    head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float z\nproperty float y\nproperty float x\nend_header\n"
    named = tmp_path / "zyx.ply"  # columns under their names
    named.write_text(head + "".join(" ".join(f"{v:.9g}" for v in p[::-1]) + "\n" for p in pts))
    placed = tmp_path / "pos.ply"  # columns x y z under the names z y x
    placed.write_text(head + "".join(" ".join(f"{v:.9g}" for v in p) + "\n" for p in pts))
    assert _theirs("equ", ref, named) == "model vertices are not equals"
    assert _theirs("equ", ref, placed) == "model vertices are equals"
    assert _ours("equ", ref, named) == "model vertices are equals"
    assert _ours("equ", ref, placed) == "model vertices are not equals"
