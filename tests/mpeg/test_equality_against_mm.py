"""``mesh_equality`` against the ``mm`` binary's ``compare --mode equ`` (skipped where it is absent), on every pair
of mmetric's own test meshes and on a shuffled capsule, with and without ``--unoriented`` and ``--earlyReturn``."""

from __future__ import annotations

import itertools
import subprocess
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.mpeg import TexturedMesh, load_textured_mesh, mesh_equality
from torchmeshmetric.structures import Mesh

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS
# plane_multi_map uses two textures (the library refuses it: one texture per mesh)
NAMES = sorted(p.stem for p in TESTS.glob("*.obj") if p.stem != "plane_multi_map")
_LABELS = ("meshes are", "triangle number", "Position differences")


def _mm_verdict(a: Path, b: Path, unoriented: bool, early: bool) -> str:
    args = [str(MM), "compare", "--mode", "equ", "--inputModelA", str(a), "--inputModelB", str(b)]
    args += [f"--earlyReturn={'true' if early else 'false'}"] + (["--unoriented"] if unoriented else [])
    out = subprocess.run(args, capture_output=True, text=True, timeout=60, check=True, cwd=a.parent).stdout
    return "\n".join(line.strip() for line in out.splitlines() if line.strip().startswith(_LABELS))


@pytest.mark.parametrize("unoriented,early", list(itertools.product((False, True), (True, False))))
def test_mmetric_test_meshes(unoriented: bool, early: bool) -> None:
    meshes = {n: load_textured_mesh(TESTS / f"{n}.obj") for n in NAMES}
    for a, b in itertools.product(NAMES, NAMES):
        ours = mesh_equality(meshes[a], meshes[b], unoriented=unoriented).report(early_return=early)
        theirs = _mm_verdict(TESTS / f"{a}.obj", TESTS / f"{b}.obj", unoriented, early)
        assert ours == theirs, (a, b)


def test_regression_script_figures() -> None:
    """The verdicts mmetric's test-compare-eq.sh asserts (where the binary agrees with the script)."""
    load = lambda n: load_textured_mesh(TESTS / f"{n}.obj")  # noqa: E731
    plane, reorder = load("plane"), load("plane_reorder")
    assert mesh_equality(plane, load("plane")).report() == "meshes are equal"
    assert mesh_equality(plane, load("plane_shifted")).report() == "meshes are equal"
    assert mesh_equality(plane, reorder).report(False).startswith("meshes are not equal, 2 different triangles")
    assert mesh_equality(plane, reorder, unoriented=True).report() == "meshes are equal"
    assert mesh_equality(plane, load("sphere")).report().startswith("meshes are not equal")


def _write(m: TexturedMesh, path: Path) -> Path:
    v, f = m.mesh.verts.numpy(), m.mesh.faces.numpy()
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_shuffled_capsule(tmp_path: Path) -> None:
    """Faces shuffled, corners rotated, some reversed, duplicates and one moved vertex: every count is mm's."""
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
        ma, mb = load_textured_mesh(a), load_textured_mesh(b)
        for unoriented, early in itertools.product((False, True), (True, False)):
            ours = mesh_equality(ma, mb, unoriented=unoriented).report(early_return=early)
            assert ours == _mm_verdict(a, b, unoriented, early), (k, unoriented, early)


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
    ma, mb, mc = (load_textured_mesh(p) for p in (a, b, c))
    for unoriented, early in itertools.product((False, True), (True, False)):
        assert mesh_equality(ma, mb, unoriented).report(early) == _mm_verdict(a, b, unoriented, early)
    assert mesh_equality(ma, mc).report() == _mm_verdict(a, c, False, True)
    assert mesh_equality(ma, mb, unoriented=True).equal
