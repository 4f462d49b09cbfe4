"""``face_sample`` against the ``mm`` binary's ``sample --mode face`` (skipped where it is absent): the points and
normals mm writes, in its order and bit for bit (its PLY prints 9 significant digits, which round-trip float32), and
its 8-bit colours, on mmetric's own test meshes (the cases of its test-sample-face.sh) and a demo frame."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from tests.mpeg.mm_sampling import assert_same_rows_in_order, demo_frame_obj, library_mesh, mm_sample
from torchmeshmetric.mpeg import TexturedMesh, face_sample
from torchmeshmetric.structures import Mesh

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS


def _check(obj: Path, texture: Path | None, resolution: int, tmp_path: Path, *extra: str) -> int:
    theirs = mm_sample(obj, texture, tmp_path, "face", "--resolution", str(resolution), *extra)
    thickness = float(extra[extra.index("--thickness") + 1]) if "--thickness" in extra else 0.0
    mesh = library_mesh(obj, texture)
    pc = face_sample(mesh, resolution=resolution, thickness=thickness, bilinear="--bilinear" in extra)
    return assert_same_rows_in_order(pc, theirs)


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
    obj, _num_verts, num_faces = demo_frame_obj(tmp_path)
    assert _check(obj, None, 256, tmp_path) > 10 * num_faces


def test_bad_arguments() -> None:
    import torch

    tri = TexturedMesh(Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]])))
    with pytest.raises(ValueError, match="resolution: expected an integer >= 1, found 0"):
        face_sample(tri, resolution=0)
    with pytest.raises(ValueError, match="thickness: expected a finite value >= 0"):
        face_sample(tri, thickness=-1.0)
