"""``subdivision_sample`` against the ``mm`` binary's ``sample --mode sdiv`` (skipped where it is absent): the same
rows (position and normal bit for bit, mm's colour bytes), compared as sorted arrays (mm recurses depth first, the
library level by level), on mmetric's test meshes (the cases of its test-sample-sdiv.sh) and a demo frame."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.mpeg import TexturedMesh, load_textured_mesh, subdivision_sample

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS


def _sorted_rows(a: np.ndarray) -> np.ndarray:
    return a[np.lexsort(a.T[::-1])]


def _check(obj: Path, texture: Path | None, area: float, depth: int, tmp_path: Path, *extra: str) -> int:
    out = tmp_path / "mm.ply"
    args = [str(MM), "sample", "--mode", "sdiv", "--areaThreshold", str(area), "--maxDepth", str(depth)]
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
    pc = subdivision_sample(mesh, max_depth=depth, area_threshold=area, bilinear="--bilinear" in extra)
    cols = [pc.points.numpy(), pc.normals.numpy()]
    if pc.colors is not None:
        cols.append(np.floor(pc.colors.numpy() + 0.5))  # mm writes roundf(colour)
    ours = np.concatenate(cols, axis=1).astype(np.float64)
    assert ours.shape == theirs.shape
    np.testing.assert_array_equal(_sorted_rows(ours), _sorted_rows(theirs))
    return ours.shape[0]


@pytest.mark.parametrize(
    "name,texture,area,depth,extra",
    [
        ("sphere", None, 1.0, 100, ()),
        ("sphere_qp8", None, 1.0, 100, ()),
        ("sphere", None, 0.001, 100, ()),
        ("degenerate", None, 1.0, 100, ()),
        ("plane", "plane.png", 1.0, 100, ("--bilinear",)),
        ("plane_irregular", "plane_10_10.png", 1.0, 100, ()),
        ("plane_irregular", "plane_16_16.png", 0.2, 100, ("--bilinear",)),
        ("triangles", None, 0.05, 100, ()),  # per-vertex colours
        ("pyramid", None, 0.5, 4, ()),  # the depth limit, not the area, stops it
    ],
)
def test_mmetric_test_meshes(
    name: str, texture: str | None, area: float, depth: int, extra: tuple[str, ...], tmp_path: Path
) -> None:
    tex = TESTS / texture if texture else None
    assert _check(TESTS / f"{name}.obj", tex, area, depth, tmp_path, *extra) > 0


def test_demo_frame(tmp_path: Path) -> None:
    from torchmeshmetric.data import demo_sequence

    frame = demo_sequence(1, resolution=48).frames[0]
    v, f = frame.verts.float().numpy(), frame.faces.numpy()
    obj = tmp_path / "frame.obj"
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    obj.write_text("\n".join(lines) + "\n")
    assert _check(obj, None, 1e-4, 100, tmp_path) > len(v)


def test_bad_arguments() -> None:
    mesh = load_textured_mesh(TESTS / "pyramid.obj")
    with pytest.raises(ValueError, match="max_depth: expected an integer >= 1, found 0"):
        subdivision_sample(mesh, max_depth=0)
    with pytest.raises(ValueError, match="area_threshold: expected a finite value > 0"):
        subdivision_sample(mesh, area_threshold=0.0)
