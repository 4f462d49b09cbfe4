"""``subdivision_sample`` against the ``mm`` binary's ``sample --mode sdiv`` (skipped where it is absent): the same
rows (position and normal bit for bit, mm's colour bytes), compared as sorted arrays (mm recurses depth first, the
library level by level), on mmetric's test meshes (the cases of its test-sample-sdiv.sh) and a demo frame."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from tests.mpeg.mm_sampling import assert_same_rows_sorted, demo_frame_obj, library_mesh, mm_sample
from torchmeshmetric.mpeg import load_textured_mesh, subdivision_sample

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS


def _check(obj: Path, texture: Path | None, area: float, depth: int, tmp_path: Path, *extra: str) -> int:
    theirs = mm_sample(obj, texture, tmp_path, "sdiv", "--areaThreshold", str(area), "--maxDepth", str(depth), *extra)
    mesh = library_mesh(obj, texture)
    pc = subdivision_sample(mesh, max_depth=depth, area_threshold=area, bilinear="--bilinear" in extra)
    return assert_same_rows_sorted(pc, theirs)


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
    obj, num_verts, _num_faces = demo_frame_obj(tmp_path)
    assert _check(obj, None, 1e-4, 100, tmp_path) > num_verts


def test_bad_arguments() -> None:
    mesh = load_textured_mesh(TESTS / "pyramid.obj")
    with pytest.raises(ValueError, match="max_depth: expected an integer >= 1, found 0"):
        subdivision_sample(mesh, max_depth=0)
    with pytest.raises(ValueError, match="area_threshold: expected a finite value > 0"):
        subdivision_sample(mesh, area_threshold=0.0)
