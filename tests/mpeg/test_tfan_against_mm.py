"""``tfan_equality`` against the ``mm`` binary's ``compare --mode eqTFAN`` (skipped where it is absent): every line mm
prints between ``eqTFAN_Epsilon = `` and ``Time on processing`` (texture maps, counts, both connectivity passes, the
verdict, the four lists' differences), on every ordered pair of mmetric's test meshes under every option set
(``--eqTFAN_earlyReturn``, ``--eqTFAN_unoriented``, ``--eqTFAN_epsilon``), on the built cases of the ``equ`` tests
(normals, colours, UV lists, texture maps), shuffled meshes (renamed vertices, UVs and faces, rotated corners) and
their altered copies, a demo frame. One test checks the lines without the binary."""

from __future__ import annotations

import itertools
import json
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from tests.mpeg.conftest import MM, MM_TESTS
from tests.mpeg.mm_compare import (
    PER_CORNER,
    QUAD,
    UV4,
    colour_cases,
    given_maps,
    mm_block,
    normal_cases,
    obj,
    texture_cases,
    uv_list_cases,
)
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg import EqualityModel, TfanEquality, load_equality_model, tfan_equality

T = MM_TESTS
NAMES = sorted(p.stem for p in T.glob("*.obj"))  # plane_multi_map too: its second map is missing (a null map)
_needs_mm = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
# (unoriented, epsilon): neither changes a line of mm v1.1.7 on meshes; every combination is run against it
_NO_EFFECT = list(itertools.product((False, True), ("0", "0.5")))


def _mm(a: Path, b: Path, early: bool, unoriented: bool = False, epsilon: str = "0", maps: tuple = (None, None)) -> str:
    options = [f"--eqTFAN_earlyReturn={'true' if early else 'false'}", f"--eqTFAN_epsilon={epsilon}"]
    return mm_block("eqTFAN", a, b, *options, *(["--eqTFAN_unoriented"] if unoriented else []), maps=maps)


def _load(path: Path, texture: Path | None = None) -> EqualityModel:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # a missing texture, which mm reports as a null map
        return load_equality_model(path, texture)


def _agree(a: Path, b: Path, maps: tuple[Path | None, Path | None] = (None, None)) -> list[str]:
    """Our lines, with and without early return, equal mm's under every option set; returns them."""
    ma, mb = _load(a, maps[0]), _load(b, maps[1])
    got = []
    for early in (True, False):
        ours = tfan_equality(ma, mb, early_return=early).report()
        for unoriented, epsilon in _NO_EFFECT:
            assert ours == _mm(a, b, early, unoriented, epsilon, maps), (a.name, b.name, early, unoriented, epsilon)
        got.append(ours)
    return got


def _all_pairs(paths: list[Path]) -> set[str]:
    """Every ordered pair (each file with itself too) agrees with mm; returns the lines seen."""
    seen: set[str] = set()
    for a, b in itertools.product(paths, paths):
        for lines in _agree(a, b):
            seen |= set(lines.splitlines())
    return seen


@_needs_mm
def test_mmetric_test_meshes() -> None:
    seen = _all_pairs([T / f"{n}.obj" for n in NAMES])
    assert {" meshes are equal", "texture maps are equal", "texture maps are not equal: mapB is null"} <= seen
    assert {"the geometry connectivity of meshes is not equal, early return.", "Normals differences: 0"} <= seen


@_needs_mm
def test_normals(tmp_path: Path) -> None:
    _all_pairs(normal_cases(tmp_path))


@_needs_mm
def test_colours(tmp_path: Path) -> None:
    _all_pairs(colour_cases(tmp_path))


@_needs_mm
def test_uv_lists(tmp_path: Path) -> None:
    """Unindexed ``vt`` lines and PLY UVs count for mm's "number of uv coordinates" (the old reader dropped them)."""
    seen = _all_pairs(uv_list_cases(tmp_path))
    assert {f"meshes are not equal, number of uv coordinates are different 0 vs {n}" for n in (3, 4)} <= seen


@_needs_mm
def test_texture_maps(tmp_path: Path) -> None:
    """The texture lines of ``equ`` before eqTFAN's: texels, size, a null map on either side, set sizes, maps given
    on the command line (``--inputMapA/B``, the CLI's ``--ref-texture`` / ``--dis-texture``)."""
    seen = _all_pairs(texture_cases(tmp_path))
    assert {
        "texture maps are equal",
        "texture maps are not equal: 3pixel differences",
        "texture maps are not equal: dimensions are not equal",
        "texture maps are not equal: mapA is null",
        "texture maps are not equal: mapB is null",
        "texture maps are not of equal: size of set A is diffrent from size of set B",
    } <= seen
    for maps in given_maps(tmp_path):
        _agree(tmp_path / "bare.obj", tmp_path / "t.obj", maps)


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


def test_every_line_of_hand_built_pairs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The lines mmetric v1.1.7's ``Compare::eqTFAN`` (source/lib/source/mmCompare.cpp) prints, without the binary.

    Its source gives each line: the texture maps first, by the same code as ``equ`` (``"texture maps are not equal: "
    << diffs << "pixel differences"``, no space); the triangle, position and UV counts (a difference ends the
    comparison); ``compareConnectivity`` on positions then on UVs, each printing "is equal", "is not equal, early
    return." or nothing; then `` meshes are equal`` (leading space) or ``N different triangles`` with N the geometry
    pass's count, and the four lists' differences as ``equ`` prints them.
    """
    texture_cases(tmp_path)  # t.obj (map t.png), t3.obj (3 texels differ), bare.obj (no map), their MTLs and PNGs
    moved = obj(
        tmp_path / "moved.obj", verts=[*QUAD[:3], (0.0, 2.0, 0.0)], uvs=UV4, corner_uvs=PER_CORNER, mtl="t3.mtl"
    )
    renamed = obj(  # t.obj with its vertices and UVs listed in reverse and its faces in another order
        tmp_path / "renamed.obj", verts=QUAD[::-1], tris=[(3, 1, 0), (3, 2, 1)], uvs=UV4[::-1],
        corner_uvs=[(3, 1, 0), (3, 2, 1)],
    )  # fmt: skip
    a = str(tmp_path / "t.obj")
    assert main(["mpeg", a, str(moved), "--mode", "eqTFAN"]) == 1
    assert capsys.readouterr().out.splitlines() == [
        "texture maps are not equal: 3pixel differences",
        "the geometry connectivity of meshes is not equal, early return.",
        "the texture connectivity of meshes is equal",
        "meshes are not equal, 1 different triangles",
        "Position differences: 1",
        "UV coords differences: 0",
        "Colors differences: 0",
        "Normals differences: 0",
    ]
    assert main(["mpeg", a, str(moved), "--mode", "eqTFAN", "--all-differences"]) == 1
    assert capsys.readouterr().out.splitlines() == [
        "texture maps are not equal: 3pixel differences",
        "the texture connectivity of meshes is equal",  # the geometry pass counted to the end: no line of its own
        "meshes are not equal, 1 different triangles",
        "Position differences: 1",
        "UV coords differences: 0",
        "Colors differences: 0",
        "Normals differences: 0",
    ]
    # renamed, without a map: equal for eqTFAN (not for equ's lists), "mapB is null"
    assert main(["mpeg", a, str(renamed), "--mode", "eqTFAN"]) == 0
    assert capsys.readouterr().out.splitlines() == [
        "texture maps are not equal: mapB is null",
        "the geometry connectivity of meshes is equal",
        "the texture connectivity of meshes is equal",
        " meshes are equal",
    ]
    # the map given on the command line replaces the MTL's (mm's --inputMapB): the same texels, "equal"
    assert main(["mpeg", a, str(renamed), "--mode", "eqTFAN", "--dis-texture", str(tmp_path / "t_copy.png")]) == 0
    assert capsys.readouterr().out.splitlines()[0] == "texture maps are equal"
    five = obj(tmp_path / "five.obj", uvs=[*UV4, (0.5, 0.5)], corner_uvs=PER_CORNER)  # an unused fifth UV
    assert main(["mpeg", a, str(five), "--mode", "eqTFAN", "--json"]) == 1
    d = json.loads(capsys.readouterr().out)
    assert (d["equal"], d["textures"], d["uvs_a"], d["uvs_b"], d["geometry"]) == (False, ["mapB is null"], 4, 5, None)
    assert d["report"].splitlines() == [
        "texture maps are not equal: mapB is null",
        "meshes are not equal, number of uv coordinates are different 4 vs 5",
    ]


def test_library_forms_and_counts() -> None:
    """Models built by hand, and any mesh form (its own per-corner UVs, no map); the count lines in mm's order."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
    f = np.array([[0, 1, 2], [1, 3, 2]])
    a = EqualityModel(v, f)
    r = tfan_equality(a, EqualityModel(v, f[:1]))
    assert isinstance(r, TfanEquality) and not r.equal and r.geometry_differences is None
    assert r.report() == "meshes are not equal, number of triangles are different 2 vs 1"
    assert tfan_equality(a, EqualityModel(v[[0, 1, 2, 3, 3]], f)).report() == (
        "meshes are not equal, number of positions are different 4 vs 5"
    )
    img = np.zeros((2, 2, 3), np.uint8)
    assert tfan_equality(EqualityModel(v, f, textures=(img,)), EqualityModel(v, f, textures=(img, None))).report() == (
        "texture maps are not of equal: size of set A is diffrent from size of set B\n"
        "the geometry connectivity of meshes is equal\n"
        "the texture connectivity of meshes is equal\n"
        " meshes are equal"
    )
    assert tfan_equality((torch.from_numpy(v), torch.from_numpy(f)), a).equal
    # models without triangles: mm's point-cloud branch (EmptyInputError before), before the position counts
    assert tfan_equality(EqualityModel(v, f[:0]), EqualityModel(v[::-1], f[:0])).report() == "model vertices are equals"
    assert tfan_equality(EqualityModel(v, f[:0]), EqualityModel(v[:3], f[:0])).report() == (
        "model vertices are not equals"
    )
