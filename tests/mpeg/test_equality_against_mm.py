"""``mesh_equality`` against the ``mm`` binary's ``compare --mode equ`` (skipped where it is absent): every line mm
prints between ``Epsilon = 0`` and ``Time on processing`` (texture maps, verdict, the four lists' differences), on
every ordered pair of mmetric's own test meshes, on built cases (normals, colours, UV lists, texture maps), on a
shuffled capsule and a demo frame, with and without ``--unoriented`` and ``--earlyReturn``."""

from __future__ import annotations

import itertools
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from PIL import Image

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.mpeg import TexturedMesh, load_equality_model, load_textured_mesh, mesh_equality
from torchmeshmetric.structures import Mesh

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS
NAMES = sorted(p.stem for p in TESTS.glob("*.obj"))  # plane_multi_map too: its second map is missing (a null map)
OPTIONS = list(itertools.product((False, True), (True, False)))  # (unoriented, early return)


def _mm_lines(
    a: Path, b: Path, unoriented: bool, early: bool, maps: tuple[Path | None, Path | None] = (None, None)
) -> str:
    """Every line mm prints for the comparison itself: after ``Epsilon = 0``, before ``Time on processing``."""
    args = [str(MM), "compare", "--mode", "equ", "--inputModelA", str(a), "--inputModelB", str(b)]
    args += [f"--earlyReturn={'true' if early else 'false'}"] + (["--unoriented"] if unoriented else [])
    for option, m in zip(("--inputMapA", "--inputMapB"), maps, strict=True):
        args += [option, str(m)] if m is not None else []
    out = subprocess.run(args, capture_output=True, text=True, timeout=60, check=True, cwd=a.parent).stdout.splitlines()
    start = next(i for i, line in enumerate(out) if line.startswith("  Epsilon = "))
    stop = next(i for i, line in enumerate(out) if line.startswith("Time on processing"))
    return "\n".join(out[start + 1 : stop])


def _ours(a: Path, b: Path, unoriented: bool, early: bool, maps: tuple[Path | None, Path | None] = (None, None)) -> str:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # a missing texture, which mm reports as a null map
        ma, mb = load_equality_model(a, maps[0]), load_equality_model(b, maps[1])
    return mesh_equality(ma, mb, unoriented=unoriented).report(early_return=early)


def _all_pairs(paths: list[Path]) -> None:
    """Every ordered pair (each file with itself too) under the four option sets: mm's lines, all of them."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        models = {p: load_equality_model(p) for p in paths}
    for a, b in itertools.product(paths, paths):
        for unoriented, early in OPTIONS:
            ours = mesh_equality(models[a], models[b], unoriented=unoriented).report(early_return=early)
            assert ours == _mm_lines(a, b, unoriented, early), (a.name, b.name, unoriented, early)


@pytest.mark.parametrize("unoriented,early", OPTIONS)
def test_mmetric_test_meshes(unoriented: bool, early: bool) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        meshes = {n: load_equality_model(TESTS / f"{n}.obj") for n in NAMES}
    for a, b in itertools.product(NAMES, NAMES):
        ours = mesh_equality(meshes[a], meshes[b], unoriented=unoriented).report(early_return=early)
        theirs = _mm_lines(TESTS / f"{a}.obj", TESTS / f"{b}.obj", unoriented, early)
        assert ours == theirs, (a, b)


def test_regression_script_figures() -> None:
    """The verdicts mmetric's test-compare-eq.sh asserts (where the binary agrees with the script)."""
    load = lambda n: load_equality_model(TESTS / f"{n}.obj")  # noqa: E731
    plane, reorder = load("plane"), load("plane_reorder")
    assert mesh_equality(plane, load("plane")).report() == "texture maps are equal\nmeshes are equal"
    assert mesh_equality(plane, load("plane_shifted")).equal
    assert "meshes are not equal, 2 different triangles" in mesh_equality(plane, reorder).report(False)
    assert mesh_equality(plane, reorder, unoriented=True).equal
    assert "meshes are not equal" in mesh_equality(plane, load("sphere")).report()


# ----------------------------------------------------------------------------------------------- built cases
QUAD = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0)]
TRIS = [(0, 1, 2), (0, 2, 3)]


def _obj(
    path: Path,
    *,
    colors: list[tuple[float, float, float] | None] | None = None,
    normals: list[tuple[float, float, float]] | None = None,
    normal_index: bool = False,
    uvs: list[tuple[float, float]] | None = None,
    corner_uvs: list[tuple[int, int, int]] | None = None,
    mtl: str | None = None,
    verts: list[tuple[float, float, float]] = QUAD,
    tris: list[tuple[int, int, int]] = TRIS,
) -> Path:
    """A small OBJ: ``v`` (with a colour where given), ``vn``, ``vt`` and faces of the chosen corner form."""
    lines = [f"mtllib {mtl}"] if mtl else []
    for k, v in enumerate(verts):
        c = colors[k] if colors is not None and k < len(colors) else None
        lines.append("v " + " ".join(f"{x:g}" for x in v) + ("" if c is None else " " + " ".join(f"{x:g}" for x in c)))
    lines += ["vn " + " ".join(f"{x:g}" for x in n) for n in normals or []]
    lines += ["vt " + " ".join(f"{x:g}" for x in t) for t in uvs or []]
    for j, tri in enumerate(tris):
        if corner_uvs is not None:
            normal = [f"/{i + 1}" if normal_index else "" for i in tri]
            corners = [f"{i + 1}/{t + 1}{n}" for i, t, n in zip(tri, corner_uvs[j], normal, strict=True)]
        else:
            corners = [f"{i + 1}//{i + 1}" if normal_index else f"{i + 1}" for i in tri]
        lines.append("f " + " ".join(corners))
    path.write_text("\n".join(lines) + "\n")
    return path


def _ply(
    path: Path,
    *,
    colors: list[tuple[int, int, int]] | None = None,
    normals: list[tuple[float, float, float]] | None = None,
    uvs: list[tuple[float, float]] | None = None,
) -> Path:
    """An ASCII PLY of the quad with optional ``red green blue``, ``nx ny nz`` and ``texture_u texture_v``."""
    props = ["x", "y", "z"]
    types = ["float"] * 3
    if normals is not None:
        props += ["nx", "ny", "nz"]
        types += ["float"] * 3
    if colors is not None:
        props += ["red", "green", "blue"]
        types += ["uchar"] * 3
    if uvs is not None:
        props += ["texture_u", "texture_v"]
        types += ["float"] * 2
    head = ["ply", "format ascii 1.0", f"element vertex {len(QUAD)}"]
    head += [f"property {t} {p}" for t, p in zip(types, props, strict=True)]
    head += [f"element face {len(TRIS)}", "property list uchar int vertex_indices", "end_header"]
    rows = []
    for k, v in enumerate(QUAD):
        row = (
            list(v)
            + list(normals[k] if normals else [])
            + list(colors[k] if colors else [])
            + list(uvs[k] if uvs else [])
        )
        rows.append(" ".join(f"{x:g}" for x in row))
    rows += [f"3 {a} {b} {c}" for a, b, c in TRIS]
    path.write_text("\n".join(head + rows) + "\n")
    return path


UP = [(0.0, 0.0, 1.0)] * 4
TILTED = [(0.0, 0.0, 1.0), (0.0, 0.6, 0.8), (0.0, 0.0, 1.0), (0.0, 0.0, 1.0)]


def test_normals(tmp_path: Path) -> None:
    """Normals differing only (OBJ ``vn``, PLY ``nx ny nz``): mm compares them when both models have one per
    position; ``v//vn`` corners make mm drop them; a model without normals is compared without."""
    files = [
        _obj(tmp_path / "up.obj", normals=UP),
        _obj(tmp_path / "tilted.obj", normals=TILTED),
        _obj(tmp_path / "indexed.obj", normals=TILTED, normal_index=True),  # dropped by mm's reader
        _obj(tmp_path / "none.obj"),
        _obj(tmp_path / "three.obj", normals=UP[:3]),  # fewer normals than positions: not compared
        _ply(tmp_path / "up.ply", normals=UP),
        _ply(tmp_path / "tilted.ply", normals=TILTED),
    ]
    _all_pairs(files)
    up, tilted = load_equality_model(files[0]), load_equality_model(files[1])
    assert not mesh_equality(up, tilted).equal and mesh_equality(up, load_equality_model(files[2])).equal


def test_colours(tmp_path: Path) -> None:
    """Per-vertex colours (OBJ ``v x y z r g b`` scaled by 255, PLY ``uchar``), differing, partial, absent."""
    grey = [(0.5, 0.5, 0.5)] * 4
    files = [
        _obj(tmp_path / "grey.obj", colors=grey),
        _obj(tmp_path / "red.obj", colors=[(1.0, 0.0, 0.0), *grey[1:]]),
        _obj(tmp_path / "almost.obj", colors=[(0.501, 0.5, 0.5), *grey[1:]]),  # the same byte after the scaling
        _obj(tmp_path / "partial.obj", colors=[None, (1.0, 0.0, 0.0), None, (0.5, 0.5, 0.5)]),
        _obj(tmp_path / "none.obj"),
        _ply(tmp_path / "grey.ply", colors=[(128, 128, 128)] * 4),
        _ply(tmp_path / "red.ply", colors=[(255, 0, 0)] + [(128, 128, 128)] * 3),
    ]
    _all_pairs(files)


def test_uv_lists(tmp_path: Path) -> None:
    """UV lists of different lengths, per corner and per position (OBJ ``vt`` without indices, PLY texture_u/v)."""
    uv4 = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    per_corner = [(0, 1, 2), (0, 2, 3)]
    files = [
        _obj(tmp_path / "four.obj", uvs=uv4, corner_uvs=per_corner),
        _obj(tmp_path / "five.obj", uvs=[*uv4, (0.5, 0.5)], corner_uvs=per_corner),  # an unused fifth UV
        _obj(tmp_path / "six.obj", uvs=[(0.5, 0.5), *uv4, (0.2, 0.2)], corner_uvs=[(1, 2, 3), (1, 3, 4)]),
        _obj(tmp_path / "moved.obj", uvs=[*uv4[:3], (0.0, 0.9)], corner_uvs=per_corner),
        _obj(tmp_path / "split.obj", uvs=[*uv4, (0.0, 0.0)], corner_uvs=[(0, 1, 2), (4, 2, 3)]),  # a seam
        _obj(tmp_path / "shuffled.obj", uvs=uv4, corner_uvs=per_corner, tris=[(2, 0, 1), (3, 0, 2)]),
        _obj(tmp_path / "vertex_uv.obj", uvs=uv4),  # no index: mm takes them per position
        _obj(tmp_path / "vertex_uv3.obj", uvs=uv4[:3]),  # no index, fewer than positions: no UVs for mm
        _obj(tmp_path / "moved_vertex.obj", verts=[*QUAD[:3], (0.0, 2.0, 0.0)], uvs=uv4, corner_uvs=per_corner),
        _ply(tmp_path / "vertex_uv.ply", uvs=uv4),
        _ply(tmp_path / "moved.ply", uvs=[*uv4[:3], (0.0, 0.9)]),
    ]
    _all_pairs(files)


def _png(path: Path, size: tuple[int, int], changed: int = 0) -> Path:
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (size[1], size[0], 3), dtype=np.uint8)
    img.reshape(-1, 3)[:changed, 0] ^= 1  # the first `changed` texels differ in red
    Image.fromarray(img).save(path)
    return path


def test_texture_maps(tmp_path: Path) -> None:
    """Maps equal, differing in pixels, in size, missing on either side, several materials, a material without a
    map, a missing map file, and maps given on the command line (``--inputMapA/B``)."""
    _png(tmp_path / "t.png", (8, 6))
    _png(tmp_path / "t_copy.png", (8, 6))
    _png(tmp_path / "t3.png", (8, 6), changed=3)
    _png(tmp_path / "wide.png", (9, 6))
    mtl = {
        "t": "newmtl m0\nmap_Kd t.png\n",
        "t_copy": "newmtl m0\nmap_Kd t_copy.png\n",
        "t3": "newmtl m0\nmap_Kd t3.png\n",
        "wide": "newmtl m0\nmap_Kd wide.png\n",
        "nomap": "newmtl m0\nKd 1 1 1\n",
        "two": "newmtl m0\nmap_Kd t.png\nnewmtl m1\nmap_Kd t3.png\n",
        "lost": "newmtl m0\nmap_Kd gone.png\n",
    }
    for name, text in mtl.items():
        (tmp_path / f"{name}.mtl").write_text(text)
    uv4 = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    files = [
        _obj(tmp_path / f"{name}.obj", uvs=uv4, corner_uvs=[(0, 1, 2), (0, 2, 3)], mtl=f"{name}.mtl") for name in mtl
    ]
    files.append(_obj(tmp_path / "bare.obj", uvs=uv4, corner_uvs=[(0, 1, 2), (0, 2, 3)]))
    files.append(_obj(tmp_path / "geometry.obj", mtl="t.mtl"))  # a map but no UVs: mm still reads the map
    files.append(_obj(tmp_path / "no_mtl_file.obj", mtl="absent.mtl"))
    _all_pairs(files)
    a, b = tmp_path / "bare.obj", tmp_path / "t.obj"
    for maps in [(tmp_path / "t3.png", None), (tmp_path / "t.png", tmp_path / "wide.png"), (None, tmp_path / "t.png")]:
        for unoriented, early in OPTIONS:
            assert _ours(a, b, unoriented, early, maps) == _mm_lines(a, b, unoriented, early, maps), maps


# ----------------------------------------------------------------------------------------------- larger meshes
def _write(m: TexturedMesh, path: Path) -> Path:
    v, f = m.mesh.verts.numpy(), m.mesh.faces.numpy()
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_shuffled_capsule(tmp_path: Path) -> None:
    """Faces shuffled, corners rotated, some reversed, duplicates and one moved vertex: every line is mm's."""
    cap = trimesh.creation.capsule(height=1.3, radius=0.45, count=[16, 16])
    v = torch.tensor(cap.vertices, dtype=torch.float32)
    f = torch.tensor(cap.faces, dtype=torch.int64)
    f = torch.cat([f, f[:7]])  # repeated triangles: the greedy one-to-one matching matters
    rng = np.random.default_rng(5)
    g = f[torch.from_numpy(rng.permutation(len(f)))]
    shift = torch.from_numpy(rng.integers(0, 3, len(g)))
    g = torch.stack([g[torch.arange(len(g)), (shift + k) % 3] for k in range(3)], dim=1)
    g[:5] = g[:5].flip(1)  # five reversed triangles: equal only when unoriented
    g = torch.cat([g[:-3], g[:3]])  # three triangles replaced by repeats of others
    w = v.clone()
    w[11] += 0.25  # a moved vertex
    a = _write(TexturedMesh(Mesh(v, f)), tmp_path / "a.obj")
    for k, (verts, faces) in enumerate([(v, g), (w, g), (w, f)]):
        b = _write(TexturedMesh(Mesh(verts, faces)), tmp_path / f"b{k}.obj")
        for unoriented, early in OPTIONS:
            assert _ours(a, b, unoriented, early) == _mm_lines(a, b, unoriented, early), (k, unoriented, early)
        # the textured mesh (no map, no normals, its own lists) gives the same lines on these plain OBJ files
        ours = mesh_equality(load_textured_mesh(a), load_textured_mesh(b)).report(False)
        assert ours == _mm_lines(a, b, False, False)


def test_demo_frame(tmp_path: Path) -> None:
    """A demo frame against itself with shuffled, rotated faces, and against the next frame (another count)."""
    from torchmeshmetric.data import demo_sequence

    frames = demo_sequence(2, resolution=48).frames
    v, f = frames[0].verts.float(), frames[0].faces
    rng = np.random.default_rng(9)
    g = f[torch.from_numpy(rng.permutation(len(f)))].roll(1, dims=1)
    g[::97] = g[::97].flip(1)
    a = _write(TexturedMesh(Mesh(v, f)), tmp_path / "a.obj")
    b = _write(TexturedMesh(Mesh(v, g)), tmp_path / "b.obj")
    c = _write(TexturedMesh(Mesh(frames[1].verts.float(), frames[1].faces)), tmp_path / "c.obj")
    for unoriented, early in OPTIONS:
        assert _ours(a, b, unoriented, early) == _mm_lines(a, b, unoriented, early)
    assert _ours(a, c, False, True) == _mm_lines(a, c, False, True)
    assert mesh_equality(load_equality_model(a), load_equality_model(b), unoriented=True).equal
