"""``mesh_equality`` against the ``mm`` binary's ``compare --mode equ`` (skipped where it is absent): every line mm
prints between ``Epsilon = 0`` and ``Time on processing`` (texture maps, verdict, the four lists' differences), on
every ordered pair of mmetric's own test meshes, on built cases (normals, colours, UV lists, texture maps), on a
shuffled capsule and a demo frame, with and without ``--unoriented`` and ``--earlyReturn``."""

from __future__ import annotations

import itertools
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from tests.mpeg.conftest import MM, MM_TESTS
from tests.mpeg.mm_compare import colour_cases, given_maps, mm_block, normal_cases, texture_cases, uv_list_cases
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
    options = [f"--earlyReturn={'true' if early else 'false'}"] + (["--unoriented"] if unoriented else [])
    return mm_block("equ", a, b, *options, maps=maps)


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
def test_normals(tmp_path: Path) -> None:
    """Normals differing only (OBJ ``vn``, PLY ``nx ny nz``): mm compares them when both models have one per
    position; ``v//vn`` corners make mm drop them; a model without normals is compared without."""
    files = normal_cases(tmp_path)
    _all_pairs(files)
    up, tilted = load_equality_model(files[0]), load_equality_model(files[1])
    assert not mesh_equality(up, tilted).equal and mesh_equality(up, load_equality_model(files[2])).equal


def test_colours(tmp_path: Path) -> None:
    """Per-vertex colours (OBJ ``v x y z r g b`` scaled by 255, PLY ``uchar``), differing, partial, absent."""
    _all_pairs(colour_cases(tmp_path))


def test_uv_lists(tmp_path: Path) -> None:
    """UV lists of different lengths, per corner and per position (OBJ ``vt`` without indices, PLY texture_u/v)."""
    _all_pairs(uv_list_cases(tmp_path))


def test_texture_maps(tmp_path: Path) -> None:
    """Maps equal, differing in pixels, in size, missing on either side, several materials, a material without a
    map, a missing map file, and maps given on the command line (``--inputMapA/B``)."""
    _all_pairs(texture_cases(tmp_path))
    a, b = tmp_path / "bare.obj", tmp_path / "t.obj"
    for maps in given_maps(tmp_path):
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
