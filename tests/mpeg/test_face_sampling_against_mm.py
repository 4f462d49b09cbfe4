"""``face_sample`` against the ``mm`` binary's ``sample --mode face`` (skipped where it is absent): the points and
normals mm writes, in its order and bit for bit (its PLY prints 9 significant digits, which round-trip float32), and
its 8-bit colours, on mmetric's own test meshes (the cases of its test-sample-face.sh) and a demo frame."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.mpeg import TexturedMesh, face_sample, load_textured_mesh
from torchmeshmetric.structures import Mesh

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS


def _read_ply(path: Path) -> np.ndarray:
    with open(path) as fh:
        for line in fh:
            if line.startswith("end_header"):
                break
        return np.loadtxt(fh, dtype=np.float64, ndmin=2)


def _check(obj: Path, texture: Path | None, resolution: int, tmp_path: Path, *extra: str) -> int:
    out = tmp_path / "mm.ply"
    args = [str(MM), "sample", "--mode", "face", "--resolution", str(resolution), "-i", str(obj), "-o", str(out)]
    args += ["--hideProgress", "-m", str(texture) if texture else "", *extra]
    subprocess.run(args, capture_output=True, text=True, timeout=300, check=True)
    theirs = _read_ply(out)
    mesh = load_textured_mesh(obj, texture)
    if texture is None:  # mm is given no map: only per-vertex colours count
        mesh = TexturedMesh(mesh.mesh, None, None, mesh.colors)
    thickness = float(extra[extra.index("--thickness") + 1]) if "--thickness" in extra else 0.0
    pc = face_sample(mesh, resolution=resolution, thickness=thickness, bilinear="--bilinear" in extra)
    ours = np.concatenate([pc.points.numpy(), pc.normals.numpy()], axis=1)
    assert ours.shape == theirs[:, :6].shape
    np.testing.assert_array_equal(ours, theirs[:, :6].astype(np.float32))  # same points, same order
    if pc.colors is not None:
        assert theirs.shape[1] == 9
        np.testing.assert_array_equal(np.floor(pc.colors.numpy() + 0.5), theirs[:, 6:])  # mm writes roundf(c)
    else:
        assert theirs.shape[1] == 6
    return ours.shape[0]


@pytest.mark.parametrize(
    "name,texture,resolution,extra",
    [
        ("sphere", None, 10, ()),
        ("sphere_qp8", None, 10, ()),
        ("sphere", None, 64, ()),
        ("degenerate", None, 10, ()),  # one zero-area face skipped
        ("triangles", None, 10, ()),  # per-vertex colours
        ("plane_irregular", "plane_10_10.png", 10, ()),
        ("plane_irregular", "plane_10_10.png", 20, ("--bilinear",)),
        ("plane_irregular", "plane_16_16.png", 33, ("--bilinear",)),
        ("pyramid", None, 30, ("--thickness", "0.3")),
    ],
)
def test_mmetric_test_meshes(
    name: str, texture: str | None, resolution: int, extra: tuple[str, ...], tmp_path: Path
) -> None:
    tex = TESTS / texture if texture else None
    assert _check(TESTS / f"{name}.obj", tex, resolution, tmp_path, *extra) > 0


def test_demo_frame(tmp_path: Path) -> None:
    from torchmeshmetric.data import demo_sequence

    frame = demo_sequence(1, resolution=48).frames[0]
    v, f = frame.verts.float().numpy(), frame.faces.numpy()
    obj = tmp_path / "frame.obj"
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    obj.write_text("\n".join(lines) + "\n")
    assert _check(obj, None, 256, tmp_path) > 10 * len(f)


def test_bad_arguments() -> None:
    import torch

    tri = TexturedMesh(Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]])))
    with pytest.raises(ValueError, match="resolution: expected an integer >= 1, found 0"):
        face_sample(tri, resolution=0)
    with pytest.raises(ValueError, match="thickness: expected a finite value >= 0"):
        face_sample(tri, thickness=-1.0)
