"""``edge_sample`` against the ``mm`` binary's ``sample --mode ediv`` (skipped where it is absent): the same
rows (position and normal bit for bit, mm's colour bytes), compared as sorted arrays (mm recurses depth first, the
library level by level), on mmetric's test meshes (the cases of its test-sample-ediv.sh) and a demo frame."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.mpeg import TexturedMesh, edge_sample, load_textured_mesh

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS


def _sorted_rows(a: np.ndarray) -> np.ndarray:
    return a[np.lexsort(a.T[::-1])]


def _check(obj: Path, texture: Path | None, area: float, depth: int, tmp_path: Path, *extra: str) -> int:
    """mm and the library on one mesh; ``area`` is the length threshold, ``depth`` the resolution."""
    out = tmp_path / "mm.ply"
    args = [str(MM), "sample", "--mode", "ediv", "--lengthThreshold", str(area), "--resolution", str(depth)]
    args += ["-i", str(obj), "-o", str(out), "--hideProgress", "-m", str(texture) if texture else "", *extra]
    subprocess.run(args, capture_output=True, text=True, timeout=300, check=True)
    with open(out) as fh:
        for line in fh:
            if line.startswith("end_header"):
                break
        data = np.loadtxt(fh, dtype=np.float64, ndmin=2)
    theirs = np.concatenate([data[:, :6].astype(np.float32).astype(np.float64), data[:, 6:]], axis=1)
    mesh = load_textured_mesh(obj, texture)
    if texture is None:  # mm is given no map: only per-vertex colours count
        mesh = TexturedMesh(mesh.mesh, None, None, mesh.colors)
    pc = edge_sample(mesh, length_threshold=area, resolution=depth, bilinear="--bilinear" in extra)
    cols = [pc.points.numpy(), pc.normals.numpy()]
    if pc.colors is not None:
        cols.append(np.floor(pc.colors.numpy() + 0.5))  # mm writes roundf(colour)
    ours = np.concatenate(cols, axis=1).astype(np.float64)
    assert ours.shape == theirs.shape
    np.testing.assert_array_equal(_sorted_rows(ours), _sorted_rows(theirs))
    return ours.shape[0]


@pytest.mark.parametrize(
    "name,texture,length,resolution,extra",
    [
        ("sphere", None, 0.0, 10, ()),  # the threshold from the resolution
        ("sphere_qp8", None, 1.0, 10, ()),  # test-sample-ediv.sh's --lengthThreshold 1
        ("sphere", None, 0.0, 64, ()),
        ("degenerate", None, 0.0, 10, ()),
        ("plane", "plane.png", 0.0, 10, ("--bilinear",)),
        ("plane_irregular", "plane_10_10.png", 0.0, 10, ()),
        ("plane_irregular", "plane_16_16.png", 0.3, 10, ("--bilinear",)),
        ("triangles", None, 0.0, 40, ()),  # per-vertex colours
        ("pyramid", None, 0.0, 25, ()),
    ],
)
def test_mmetric_test_meshes(
    name: str, texture: str | None, length: float, resolution: int, extra: tuple[str, ...], tmp_path: Path
) -> None:
    tex = TESTS / texture if texture else None
    assert _check(TESTS / f"{name}.obj", tex, length, resolution, tmp_path, *extra) > 0


def test_demo_frame(tmp_path: Path) -> None:
    from torchmeshmetric.data import demo_sequence

    frame = demo_sequence(1, resolution=48).frames[0]
    v, f = frame.verts.float().numpy(), frame.faces.numpy()
    obj = tmp_path / "frame.obj"
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    obj.write_text("\n".join(lines) + "\n")
    assert _check(obj, None, 0.0, 300, tmp_path) > len(v)


def test_bad_arguments() -> None:
    mesh = load_textured_mesh(TESTS / "pyramid.obj")
    with pytest.raises(ValueError, match="resolution: expected an integer >= 1"):
        edge_sample(mesh, resolution=0)
    with pytest.raises(ValueError, match="length_threshold: expected a finite value >= 0"):
        edge_sample(mesh, length_threshold=-1.0)
