"""``prnd_sample`` against the ``mm`` binary's ``sample --mode prnd`` (skipped where it is absent): mmetric's
"pseudo-random" points are a deterministic R2 sequence, so they are compared point by point, in mm's order and bit
for bit, with mm's colour bytes, on mmetric's test meshes (the cases of its test-sample-prnd.sh) and a demo frame."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.mpeg import TexturedMesh, load_textured_mesh, prnd_sample

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS


def _check(obj: Path, texture: Path | None, n: int, tmp_path: Path, *extra: str) -> int:
    out = tmp_path / "mm.ply"
    args = [str(MM), "sample", "--mode", "prnd", "--nbSamples", str(n), "-i", str(obj), "-o", str(out)]
    args += ["--hideProgress", "-m", str(texture) if texture else "", *extra]
    subprocess.run(args, capture_output=True, text=True, timeout=300, check=True)
    with open(out) as fh:
        for line in fh:
            if line.startswith("end_header"):
                break
        theirs = np.loadtxt(fh, dtype=np.float64, ndmin=2)
    mesh = load_textured_mesh(obj, texture)
    if texture is None:  # mm is given no map: only per-vertex colours count
        mesh = TexturedMesh(mesh.mesh, None, None, mesh.colors)
    pc = prnd_sample(mesh, num_samples=n, bilinear="--bilinear" in extra)
    ours = np.concatenate([pc.points.numpy(), pc.normals.numpy()], axis=1)
    assert ours.shape == theirs[:, :6].shape
    np.testing.assert_array_equal(ours, theirs[:, :6].astype(np.float32))  # same points, same order
    if pc.colors is not None:
        np.testing.assert_array_equal(np.floor(pc.colors.numpy() + 0.5), theirs[:, 6:])  # mm writes roundf(c)
    else:
        assert theirs.shape[1] == 6
    return ours.shape[0]


@pytest.mark.parametrize(
    "name,texture,n,extra",
    [
        ("sphere", None, 50, ()),  # fewer samples than faces: the corners only
        ("sphere", None, 100000, ()),
        ("sphere_qp8", None, 20000, ()),
        ("degenerate", None, 1000, ()),
        ("triangles", None, 500, ()),  # corners keep their colour, inner points are black (as mm)
        ("plane", "plane.png", 50, ("--bilinear",)),
        ("plane_irregular", "plane_10_10.png", 5000, ()),
    ],
)
def test_mmetric_test_meshes(name: str, texture: str | None, n: int, extra: tuple[str, ...], tmp_path: Path) -> None:
    tex = TESTS / texture if texture else None
    assert _check(TESTS / f"{name}.obj", tex, n, tmp_path, *extra) >= n


def test_demo_frame(tmp_path: Path) -> None:
    from torchmeshmetric.data import demo_sequence

    frame = demo_sequence(1, resolution=48).frames[0]
    v, f = frame.verts.float().numpy(), frame.faces.numpy()
    obj = tmp_path / "frame.obj"
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    obj.write_text("\n".join(lines) + "\n")
    assert _check(obj, None, 200000, tmp_path) >= 200000


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="num_samples: expected an integer >= 1, found 0"):
        prnd_sample(load_textured_mesh(TESTS / "pyramid.obj"), num_samples=0)
