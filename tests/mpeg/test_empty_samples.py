"""A mesh that gives no MPEG sample is named, with the reason (issue 23).

Before: a mesh whose every face has zero area failed with "cloud: expected at least one point, found an empty point
cloud" — neither which mesh (REF or DIS, which file) nor why. Now the error names the mesh (``ref``/``dis`` in the
library, ``REF 'file'``/``DIS 'file'`` on the command line, ``<sequence> frame k`` in a sequence) and says that all its
faces have zero area (or, in grid mode, that no grid ray reaches the surface).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from torchmeshmetric._checks import EmptyInputError
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg import mpeg_metrics, mpeg_sequence
from torchmeshmetric.mpeg.comparison.metric import MpegPSNR
from torchmeshmetric.mpeg.comparison.pcc import mpeg_compare
from torchmeshmetric.mpeg.core.point_cloud import PointCloud
from torchmeshmetric.mpeg.sampling.vertex_sampling import vertex_sample

GOOD = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]), torch.tensor([[0, 1, 2], [0, 1, 3], [0, 2, 3]]))


@st.composite
def zero_area_meshes(draw: st.DrawFn) -> tuple[torch.Tensor, torch.Tensor]:
    """Meshes whose every face is degenerate: repeated corners, collinear corners, or all vertices on one line."""
    n = draw(st.integers(3, 12))
    # Integers (times a power of two): exact in float32, so the corners are exactly collinear after rounding too
    # (a float64-collinear face rounded to float32 may keep a sliver of area above DBL_EPSILON, a true surface).
    scale = 2.0 ** draw(st.integers(-20, 20))
    base = np.array(draw(st.lists(st.integers(-10, 10), min_size=3, max_size=3)), dtype=np.float64)
    direction = np.array(draw(st.lists(st.integers(-3, 3), min_size=3, max_size=3)), dtype=np.float64)
    t = np.array(draw(st.lists(st.integers(-5, 5), min_size=n, max_size=n)), dtype=np.float64)
    verts = (base + t[:, None] * direction) * scale  # every vertex on one line (or one point): zero-area faces
    num_faces = draw(st.integers(1, 10))
    faces = np.array(
        draw(st.lists(st.lists(st.integers(0, n - 1), min_size=3, max_size=3), min_size=num_faces, max_size=num_faces))
    )
    return torch.tensor(verts, dtype=torch.float32), torch.tensor(faces)


@settings(max_examples=40, deadline=None)
@given(mesh=zero_area_meshes(), sampling=st.sampled_from(["grid", "mesh"]), side=st.sampled_from(["ref", "dis"]))
def test_a_mesh_of_zero_area_faces_is_named_with_the_reason(mesh, sampling, side):
    ref, dis = (mesh, GOOD) if side == "ref" else (GOOD, mesh)
    with pytest.raises(
        EmptyInputError,
        match=rf"^{side}: no point was sampled: all {mesh[1].shape[0]} face\(s\) "
        r"have zero area",
    ):
        mpeg_metrics(ref, dis, sampling=sampling, grid_size=16)


def test_the_samplers_and_the_comparison_name_what_they_were_given():
    flat = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]), torch.tensor([[0, 1, 2]]))
    with pytest.raises(EmptyInputError, match=r"^frame 7: no point was sampled: all 1 face\(s\) have zero area"):
        vertex_sample(flat, name="frame 7")
    empty = PointCloud(torch.zeros(0, 3))
    some = PointCloud(torch.zeros(1, 3))
    for ref, dis, side in ((empty, some, "ref"), (some, empty, "dis")):
        with pytest.raises(EmptyInputError, match=rf"^{side}: expected at least one point, found an empty point cloud"):
            mpeg_compare(ref, dis)


def test_a_sequence_names_the_frame_and_the_metric_its_argument():
    flat = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]), torch.tensor([[0, 1, 2]]))
    with pytest.raises(EmptyInputError, match=r"^distorted frame 1: no point was sampled: all 1 face"):
        mpeg_sequence([GOOD, GOOD], [GOOD, flat], sampling="mesh")
    with pytest.raises(EmptyInputError, match=r"^preds: no point was sampled"):
        MpegPSNR(sampling="mesh").update(flat, GOOD)


def test_a_grid_that_misses_the_surface_says_so():
    # A sliver of area ~1e-7 (above DBL_EPSILON in float32: a surface mmetric samples) that no ray of a 16-step grid
    # over its box hits.
    sliver = (torch.tensor([[0.0, 0, 0], [3, 1, 0], [1, 1 / 3, 1e-7]], dtype=torch.float64), torch.tensor([[0, 1, 2]]))
    from torchmeshmetric.mpeg import mpeg_point_cloud

    with pytest.raises(EmptyInputError, match=r"^dis: no point was sampled: no ray of the 16-step grid over its"):
        mpeg_point_cloud(sliver, "grid", grid_size=16, name="dis")
    assert vertex_sample(sliver).num_points == 3  # a surface: mesh sampling gives its corners


@pytest.mark.parametrize("side", ["REF", "DIS"])
@pytest.mark.parametrize("sampling", ["grid", "mesh"])
def test_the_command_line_names_the_file(tmp_path: Path, capsys: pytest.CaptureFixture[str], side, sampling):
    good = tmp_path / "good.obj"
    good.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\n")
    flat = tmp_path / "flat.obj"
    flat.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n")
    ref, dis = (flat, good) if side == "REF" else (good, flat)
    grid = ["--grid-size", "16"] if sampling == "grid" else []  # refused in mesh mode, where it has no effect
    assert main(["mpeg", str(ref), str(dis), "--sampling", sampling, *grid]) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"{side} '{flat}': no point was sampled: all 2 face(s) have zero area" in err
