"""``mpeg --mode pcqm`` against the ``mm`` binary (skipped where it is absent): every printed figure, as printed.

mm prints 16 PCQM figures (the score, its PSNR, and the one-frame statistics of both) with 9 significant digits;
ours must print the same strings. Measured on these cases, on the demo frames at resolution 160/256 (119k/306k
points) and on scores made of rounding noise only (the sphere pair at --radiusCurvature 0.05 scores 1.6e-41): every
line identical, and the per-point curvatures and features bit-identical to an Eigen 3.3.5 build of PCQM's fits. So
the comparison is exact string equality, no tolerance.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.mpeg.conftest import MM, MM_TESTS
from torchmeshmetric.cli import main

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")

TESTS = MM_TESTS
_OPTS = {"radius_curvature": "--radiusCurvature", "knn": "--thresholdKnnSearch", "radius_factor": "--radiusFactor"}
_CLI = {"radius_curvature": "--radius-curvature", "knn": "--threshold-knn-search", "radius_factor": "--radius-factor"}


def _mm_lines(a: Path, b: Path, cwd: Path, maps: tuple[Path, Path] | None, **opts: float) -> list[str]:
    args = [str(MM), "compare", "--mode", "pcqm", "--inputModelA", str(a), "--inputModelB", str(b)]
    if maps is not None:
        args += ["--inputMapA", str(maps[0]), "--inputMapB", str(maps[1])]
    for k, v in opts.items():
        args += [_OPTS[k], str(v)]
    # PCQM writes features_extracted.csv into its working directory
    out = subprocess.run(args, capture_output=True, text=True, timeout=600, check=True, cwd=cwd).stdout
    return [line for line in out.splitlines() if line.startswith("PCQM")]


def _our_lines(
    a: Path, b: Path, maps: tuple[Path, Path] | None, capsys: pytest.CaptureFixture[str], **opts: float
) -> list[str]:
    args = ["mpeg", str(a), str(b), "--mode", "pcqm"]
    if maps is not None:
        args += ["--ref-texture", str(maps[0]), "--dis-texture", str(maps[1])]
    for k, v in opts.items():
        args += [_CLI[k], str(v)]
    assert main(args) == 0
    return [line for line in capsys.readouterr().out.splitlines() if line.startswith("PCQM")]


def _check(a: Path, b: Path, tmp: Path, capsys: pytest.CaptureFixture[str], maps: tuple[Path, Path] | None = None,
           **opts: float) -> list[str]:  # fmt: skip
    theirs = _mm_lines(a, b, tmp, maps, **opts)
    ours = _our_lines(a, b, maps, capsys, **opts)
    assert len(theirs) == 16
    assert ours == theirs
    return ours


def _sample(name: str, out: Path, texture: Path | None = None, resolution: int = 64) -> Path:
    args = [str(MM), "sample", "--mode", "face", "--resolution", str(resolution), "--inputModel", str(TESTS / name)]
    if texture is not None:
        args += ["--inputMap", str(texture)]
    subprocess.run([*args, "--outputModel", str(out)], capture_output=True, timeout=300, check=True)
    return out


def test_sampled_sphere_clouds(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = _sample("sphere.obj", tmp_path / "a.ply", resolution=256)
    b = _sample("sphere_qp8.obj", tmp_path / "b.ply", resolution=256)
    lines = _check(a, b, tmp_path, capsys)
    assert float(lines[0].split(":")[1]) > 1e-10  # a real score (4.68e-10), not rounding noise
    # ill-conditioned fits of 4-5 points (curvatures up to 1e6) amplify the last bits of Eigen's vectorised sums
    _check(a, b, tmp_path, capsys, radius_curvature=0.002, radius_factor=1.0)
    _check(b, a, tmp_path, capsys, radius_curvature=0.01, knn=10)


@pytest.mark.parametrize("dis", ["plane_qp8.obj", "plane_shifted.obj"])
def test_sampled_textured_plane_clouds(dis: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tex = TESTS / "plane.png"
    a = _sample("plane.obj", tmp_path / "a.ply", tex)
    b = _sample(dis, tmp_path / "b.ply", tex)
    _check(a, b, tmp_path, capsys, radius_factor=1.0)
    _check(b, a, tmp_path, capsys, radius_curvature=0.004, knn=12)


@pytest.mark.parametrize(
    ("a", "b", "textures", "opts"),
    [
        ("sphere.obj", "sphere_qp8.obj", None, {}),
        ("sphere.obj", "sphere_qp8.obj", None, {"radius_curvature": 0.05}),  # 1.6e-41: rounding noise, still equal
        ("plane.obj", "plane_irregular.obj", ("plane.png", "plane.png"), {"radius_curvature": 0.05}),
        ("plane.obj", "plane_irregular.obj", ("plane.png", "plane.png"), {"radius_curvature": 0.2, "knn": 8}),
        ("plane_shifted.obj", "plane_reorder.obj", ("plane_16_16.png", "plane_10_10.png"), {"radius_curvature": 0.1}),
        ("pyramid.obj", "triangles.obj", None, {"radius_curvature": 0.3}),
        # extremes mm prints a figure for (issue 41): a radius whose square overflows, more neighbours than points
        ("sphere.obj", "sphere_qp8.obj", None, {"radius_curvature": 1e200}),
        ("plane.obj", "plane_irregular.obj", ("plane.png", "plane.png"), {"radius_curvature": 1e200}),
        ("pyramid.obj", "triangles.obj", None, {"radius_curvature": 0.3, "knn": 5000}),
    ],
)
def test_meshes_sampled_as_mm(
    a: str, b: str, textures: tuple[str, str] | None, opts: dict[str, float], tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    maps = None if textures is None else (TESTS / textures[0], TESTS / textures[1])
    _check(TESTS / a, TESTS / b, tmp_path, capsys, maps, **opts)


def _coloured_obj(mesh: object, path: Path, shift: float = 0.0) -> Path:
    v = mesh.verts.numpy().astype(np.float64) + shift  # type: ignore[attr-defined]
    f = mesh.faces.numpy()  # type: ignore[attr-defined]
    t = (v - v.min(0)) / (v.max(0) - v.min(0))
    c = np.stack([t[:, 0], 0.5 + 0.5 * np.sin(7 * t[:, 1]), t[:, 2] ** 2], axis=1)
    rows = [f"v {x:.9g} {y:.9g} {z:.9g} {r:.6f} {g:.6f} {bb:.6f}" for (x, y, z), (r, g, bb) in zip(v, c, strict=True)]
    rows += [f"f {i + 1} {j + 1} {k + 1}" for i, j, k in f]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_demo_frame_pair(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from torchmeshmetric.data import demo_sequence

    frames = demo_sequence(2, resolution=96).frames
    a = _coloured_obj(frames[0], tmp_path / "f0.obj")
    b = _coloured_obj(frames[1], tmp_path / "f1.obj")
    _check(a, b, tmp_path, capsys)
    # all-negative coordinates: PCQM's box measure |min| + |max| with its maxima started at DBL_MIN
    a2 = _coloured_obj(frames[0], tmp_path / "g0.obj", shift=-5.0)
    b2 = _coloured_obj(frames[1], tmp_path / "g1.obj", shift=-5.0)
    _check(a2, b2, tmp_path, capsys, radius_curvature=0.002)


def test_mesh_samples_in_mm_order(tmp_path: Path) -> None:
    """The sampled mesh comes in mm's order (the k-d tree's choice among equidistant points depends on it)."""
    from torchmeshmetric.mpeg.sampling.model_cloud import load_model_cloud

    out = tmp_path / "b.obj"
    args = [str(MM), "compare", "--mode", "pcqm", "--inputModelA", str(TESTS / "plane.obj"), "--inputModelB",
            str(TESTS / "plane_irregular.obj"), "--inputMapA", str(TESTS / "plane.png"), "--inputMapB",
            str(TESTS / "plane.png"), "--outputModelB", str(out)]  # fmt: skip
    subprocess.run(args, capture_output=True, timeout=300, check=True, cwd=tmp_path)
    theirs = np.array([ln.split()[1:4] for ln in out.read_text().splitlines() if ln.startswith("v ")], np.float32)
    ours = load_model_cloud(TESTS / "plane_irregular.obj", TESTS / "plane.png").points.numpy()
    assert np.array_equal(ours, theirs)
