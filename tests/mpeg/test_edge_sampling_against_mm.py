"""``edge_sample`` against the ``mm`` binary's ``sample --mode ediv`` (skipped where it is absent): the same
rows (position and normal bit for bit, mm's colour bytes), compared as sorted arrays (mm recurses depth first, the
library level by level), on mmetric's test meshes (the cases of its test-sample-ediv.sh) and a demo frame."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from tests.mpeg.mm_sampling import assert_same_rows_sorted, demo_frame_obj, library_mesh, mm_sample
from torchmeshmetric.mpeg import edge_sample, load_textured_mesh

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS


def _check(obj: Path, texture: Path | None, area: float, depth: int, tmp_path: Path, *extra: str) -> int:
    """mm and the library on one mesh; ``area`` is the length threshold, ``depth`` the resolution."""
    theirs = mm_sample(
        obj, texture, tmp_path, "ediv", "--lengthThreshold", str(area), "--resolution", str(depth), *extra
    )
    mesh = library_mesh(obj, texture)
    pc = edge_sample(mesh, length_threshold=area, resolution=depth, bilinear="--bilinear" in extra)
    return assert_same_rows_sorted(pc, theirs)


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
    obj, num_verts, _num_faces = demo_frame_obj(tmp_path)
    assert _check(obj, None, 0.0, 300, tmp_path) > num_verts


def test_bad_arguments() -> None:
    mesh = load_textured_mesh(TESTS / "pyramid.obj")
    with pytest.raises(ValueError, match="resolution: expected an integer >= 1"):
        edge_sample(mesh, resolution=0)
    with pytest.raises(ValueError, match="length_threshold: expected a finite value >= 0"):
        edge_sample(mesh, length_threshold=-1.0)
