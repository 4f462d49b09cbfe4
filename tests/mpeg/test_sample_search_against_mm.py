"""``sample`` with mmetric's sample-count search (``--nbSamplesMin/Max``) and sdiv's ``--mapThreshold`` against the
``mm`` binary (skipped where it is absent): the written PLY files are equal byte for byte."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
import torch

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg import PointCloud
from torchmeshmetric.mpeg.sampling.sample_count_search import search_sample_count

T = MM_TESTS
_needs_mm = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

CASES = [
    # (mesh, mm options, our options): searches that converge, stop at --maxIterations, keep or lose colours
    ("sphere.obj", "--mode sdiv --nbSamplesMin 5000 --nbSamplesMax 6000", "--mode sdiv --num-samples-min 5000 "
     "--num-samples-max 6000"),
    ("triangles.obj", "--mode sdiv --nbSamplesMin 20000 --nbSamplesMax 21000", "--mode sdiv --num-samples-min "
     "20000 --num-samples-max 21000"),
    ("plane.obj", "--mode sdiv --nbSamplesMin 2000 --nbSamplesMax 2100 --maxIterations 3", "--mode sdiv "
     "--num-samples-min 2000 --num-samples-max 2100 --max-iterations 3"),
    ("plane.obj", "--mode sdiv --nbSamplesMin 10 --nbSamplesMax 90000", "--mode sdiv --num-samples-min 10 "
     "--num-samples-max 90000"),
    ("sphere.obj", "--mode face --nbSamplesMin 20000 --nbSamplesMax 30000", "--mode face --num-samples-min 20000 "
     "--num-samples-max 30000"),
    ("plane.obj", "--mode face --nbSamplesMin 500 --nbSamplesMax 1500", "--mode face --num-samples-min 500 "
     "--num-samples-max 1500"),
    ("sphere_qp8.obj", "--mode ediv --nbSamplesMin 50 --nbSamplesMax 2000", "--mode ediv --num-samples-min 50 "
     "--num-samples-max 2000"),
    # --mapThreshold: texels more than one apart keep a face splitting below the area threshold
    ("plane.obj", f"--mode sdiv --mapThreshold --areaThreshold 5 -m {T}/plane_16_16.png", "--mode sdiv "
     f"--map-threshold --area-threshold 5 --texture {T}/plane_16_16.png"),
    ("plane_irregular.obj", f"--mode sdiv --mapThreshold --areaThreshold 1 -m {T}/plane_16_16.png", "--mode sdiv "
     f"--map-threshold --area-threshold 1 --texture {T}/plane_16_16.png"),
    ("plane_qp8.obj", f"--mode sdiv --mapThreshold --areaThreshold 0.2 --bilinear -m {T}/plane_10_10.png", "--mode "
     f"sdiv --map-threshold --area-threshold 0.2 --bilinear --texture {T}/plane_10_10.png"),
]  # fmt: skip


@_needs_mm
@pytest.mark.parametrize("mesh,theirs,ours", CASES)
def test_files_equal_mm(tmp_path: Path, mesh: str, theirs: str, ours: str, capsys: pytest.CaptureFixture[str]) -> None:
    mm_out, our_out = tmp_path / "mm.ply", tmp_path / "ours.ply"
    args = [str(MM), "sample", *theirs.split(), "-i", str(T / mesh), "-o", str(mm_out), "--hideProgress"]
    subprocess.run(args, capture_output=True, text=True, timeout=300, check=True)
    assert main(["sample", str(T / mesh), str(our_out), *ours.split()]) == 0
    assert our_out.read_bytes() == mm_out.read_bytes()
    capsys.readouterr()


def test_map_threshold_splits_more(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tex = str(T / "plane_16_16.png")
    base = ["sample", str(T / "plane.obj"), "--mode", "sdiv", "--area-threshold", "5", "--texture", tex]
    assert main([*base[:2], str(tmp_path / "a.ply"), *base[2:]]) == 0
    assert main([*base[:2], str(tmp_path / "b.ply"), *base[2:], "--map-threshold"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("Generated 41 points") and out[1].startswith("Generated 540 points")


def _cloud(n: int) -> PointCloud:
    return PointCloud(torch.zeros(n, 3))


def test_threshold_search_in_float32() -> None:
    """A threshold that removes points as it grows: mmetric's float32 bisection, and its count of earlier points."""
    seen: list[float] = []

    def sample(t: float) -> PointCloud:
        seen.append(t)
        return _cloud(int(1000 / t))

    r = search_sample_count(sample, "threshold", 300, 320)
    assert seen == [1.0, 2.0, 4.0, 3.0, 3.5, 3.25]  # doubles past the range, then halves the bracket
    assert (r.value, r.cloud.num_points, r.iterations) == (3.25, 307, 5)
    assert r.earlier_points == sum(int(1000 / t) for t in seen[:-1])
    r = search_sample_count(sample, "threshold", 10, 11, max_iterations=2)  # stops with the count outside
    assert (r.iterations, r.cloud.num_points) == (2, 250)
    with pytest.raises(ValueError, match="expected 1 <= min < max"):
        search_sample_count(sample, "threshold", 10, 10)


def test_cli_search_refusals(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert main(["sample", str(mesh), str(tmp_path / "o.ply"), "--mode", "prnd", "--num-samples-min", "5"]) == 1
    assert "not of prnd mode" in capsys.readouterr().err
    assert main(["sample", str(mesh), str(tmp_path / "o.ply"), "--num-samples-min", "5", "--num-samples-max", "5"]) == 1
    assert "error: --num-samples-min, --num-samples-max: expected 1 <= min < max" in capsys.readouterr().err
    argv = ["sample", str(mesh), str(tmp_path / "o.ply"), "--num-samples-min", "5", "--num-samples-max", "9"]
    assert main([*argv, "--max-iterations", "-1"]) == 1
    assert "error: --max-iterations: expected >= 0, found -1" in capsys.readouterr().err
