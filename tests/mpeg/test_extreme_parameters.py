"""Extreme parameters end in a typed error naming the option, never a raw numeric or allocator error; numpy
scalars are taken wherever Python numbers are (issue 41, themes 4 and 6). mm's figures for the extremes it prints
one for (--radius-curvature 1e200, more neighbours than points) are compared in test_pcqm_against_mm.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from torchmeshmetric._checks import SizeLimitError
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg import PointCloud
from torchmeshmetric.mpeg.comparison.pcqm import mpeg_pcqm
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.mpeg.sampling.edge_sampling import edge_sample
from torchmeshmetric.mpeg.sampling.face_sampling import face_sample
from torchmeshmetric.mpeg.sampling.prnd_sampling import prnd_sample
from torchmeshmetric.mpeg.sampling.subdivision_sampling import subdivision_sample
from torchmeshmetric.simplification import simplify_anchored_qem
from torchmeshmetric.structures import Mesh

QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n"


def _quad() -> TexturedMesh:
    verts = torch.tensor([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    return TexturedMesh(Mesh(verts, torch.tensor([[0, 1, 2], [0, 2, 3]])))


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["--resolution", "100000000"], "--resolution: 100000000 asks for about"),
        (["--resolution", "16", "--thickness", "1e30"], "--resolution, --thickness: (16, 1e+30) asks for about"),
        (["--mode", "prnd", "--num-samples", "10000000000000000000"], "--num-samples: 10000000000000000000 asks"),
        (["--mode", "ediv", "--resolution", "1000000000"], "--resolution: 1000000000 asks for about"),
        (["--mode", "ediv", "--length-threshold", "1e-30"], "--length-threshold: 1e-30 asks for about"),
        (["--mode", "sdiv", "--area-threshold", "1e-30"], "--area-threshold: 1e-30 asks for about"),
    ],
    ids=["face-resolution", "face-thickness", "prnd-count", "ediv-resolution", "ediv-length", "sdiv-area"],
)
def test_sample_sizes_beyond_memory_name_the_option(tmp_path: Path, capsys, argv, option):
    mesh = tmp_path / "q.obj"
    mesh.write_text(QUAD)
    out = tmp_path / "out.ply"
    assert main(["sample", str(mesh), str(out), *argv]) == 1
    line = capsys.readouterr().err.splitlines()[-1]
    assert line.startswith("torchmeshmetric sample: error: " + option) and "GiB" in line, line
    assert not out.exists()


@pytest.mark.parametrize(
    "call",
    [
        lambda m: face_sample(m, resolution=10**8),
        lambda m: prnd_sample(m, num_samples=10**19),
        lambda m: edge_sample(m, length_threshold=1e-30),
        lambda m: subdivision_sample(m, area_threshold=1e-30),
    ],
    ids=["face", "prnd", "ediv", "sdiv"],
)
def test_sampler_sizes_beyond_memory_are_size_limit_errors(call):
    with pytest.raises(SizeLimitError, match=r"^(resolution|num_samples|length_threshold|area_threshold): "):
        call(_quad())


def test_pcqm_knn_beyond_memory_names_the_option(tmp_path: Path, capsys):
    pts = torch.rand(50, 3, generator=torch.Generator().manual_seed(0))
    with pytest.raises(SizeLimitError, match=r"^knn: 1000000000000 asks for about .* neighbour slots"):
        mpeg_pcqm(PointCloud(pts), PointCloud(pts), knn=10**12)
    mesh = tmp_path / "q.obj"
    mesh.write_text(QUAD)
    assert main(["mpeg", str(mesh), str(mesh), "--mode", "pcqm", "--threshold-knn-search", "1000000000000"]) == 1
    line = capsys.readouterr().err.splitlines()[-1]
    assert line.startswith("torchmeshmetric mpeg: error: --threshold-knn-search: 1000000000000 asks for about"), line


@pytest.mark.parametrize("scalar", [np.int64, np.int32, np.uint16])
def test_numpy_integer_counts_give_the_python_integer_result(scalar):
    m = _quad()
    assert face_sample(m, resolution=scalar(8)).points.tolist() == face_sample(m, resolution=8).points.tolist()
    assert prnd_sample(m, num_samples=scalar(40)).points.tolist() == prnd_sample(m, num_samples=40).points.tolist()
    ediv = edge_sample(m, resolution=scalar(8)).points.tolist()
    assert ediv == edge_sample(m, resolution=8).points.tolist()
    sdiv = subdivision_sample(m, max_depth=scalar(3), area_threshold=0.01).points.tolist()
    assert sdiv == subdivision_sample(m, max_depth=3, area_threshold=0.01).points.tolist()


@pytest.mark.parametrize("bad", [True, 2.0, "8"])
def test_non_integer_counts_are_still_refused(bad):
    with pytest.raises(ValueError, match=r"^resolution: expected an integer >= 1"):
        face_sample(_quad(), resolution=bad)


def test_numpy_float_weight_in_anchored_qem():
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=2)
    mesh = Mesh(torch.tensor(s.vertices), torch.tensor(s.faces))
    anchors = mesh.verts[::7] * 1.01
    want = simplify_anchored_qem(mesh, anchors, 0.5, weight=0.25)
    got = simplify_anchored_qem(mesh, anchors, 0.5, weight=np.float32(0.25))
    assert torch.equal(got.verts, want.verts) and torch.equal(got.faces, want.faces)
    with pytest.raises(TypeError, match=r"^weight: expected a float"):
        simplify_anchored_qem(mesh, anchors, 0.5, weight=np.bool_(True))


def test_an_allocation_that_fails_below_the_physical_memory_names_the_option(tmp_path: Path, capsys, monkeypatch):
    def no_memory(*args: object, **kwargs: object) -> None:
        raise MemoryError("Unable to allocate 232. GiB for an array with shape (10400000000, 3) and data type float64")

    monkeypatch.setattr("torchmeshmetric.mpeg.sampling.face_sampling.face_sample", no_memory)
    mesh = tmp_path / "q.obj"
    mesh.write_text(QUAD)
    assert main(["sample", str(mesh), str(tmp_path / "o.ply"), "--resolution", "100000"]) == 1
    line = capsys.readouterr().err.splitlines()[-1]
    assert "error: --resolution: the face sampling needs more memory than is free here (Unable to allocate" in line


def test_sample_sizes_are_checked_against_the_available_memory_and_working_set(tmp_path: Path, capsys, monkeypatch):
    """Review X: the check compared the points' least bytes (24 each) with the *physical* memory, so `sample
    --resolution 10000` (at least 9.4 GB) passed on a 23 GB machine with far less free, and its arrays would then
    meet the OOM killer. It now compares the measured working set (96 bytes a point in face mode) with the memory
    available; here a 50 MB machine, so the 1.2e6 points of a unit square at resolution 1000 (29 MB by the old count,
    about 116 MB really) are refused. Nothing is allocated for real: the figure is replaced."""
    monkeypatch.setattr("torchmeshmetric._checks.available_memory", lambda: 50 * 2**20)
    mesh = tmp_path / "q.obj"
    mesh.write_text(QUAD)
    out = tmp_path / "o.ply"
    assert main(["sample", str(mesh), str(out), "--resolution", "1000"]) == 1
    line = capsys.readouterr().err.splitlines()[-1]
    want = "error: --resolution: 1000 asks for about 1.21e+06 points of mesh, about 0.108 GiB, more than the 0.0488 GiB"
    assert line == f"torchmeshmetric sample: {want} of memory available; choose a smaller value", line
    assert not out.exists()
    assert main(["sample", str(mesh), str(out), "--resolution", "100"]) == 0  # 1e4 points: about 1 MB
