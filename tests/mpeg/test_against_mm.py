"""New figures from the ``mm`` binary itself (skipped where it is absent): sampled points, point by point, and the
comparison's figures, on shapes and settings the stored references do not cover (no useNormal, a small grid,
an off-centre box, a mesh that reaches outside the box)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from tests.mpeg.conftest import MM
from torchmeshmetric.mpeg import PointCloud, grid_sample, mpeg_compare, vertex_sample

pytestmark = pytest.mark.skipif(not MM.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")


def _obj(mesh: trimesh.Trimesh, path: Path) -> Path:
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in mesh.vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def _read_ply(path: Path) -> np.ndarray:
    with open(path) as fh:
        count = 0
        for line in fh:
            if line.startswith("element vertex"):
                count = int(line.split()[2])
            if line.startswith("end_header"):
                break
        data = np.loadtxt(fh, dtype=np.float64, ndmin=2)
    assert data.shape[0] == count
    return data.astype(np.float32)


def _mm(*args: str) -> str:
    run = subprocess.run([str(MM), *args], capture_output=True, text=True, timeout=300, check=True)
    return run.stdout


def _figure(out: str, label: str) -> float:
    return float(re.findall(re.escape(label) + r"\s*:\s*(\S+)", out)[-1])


def _shapes(tmp_path: Path) -> tuple[Path, Path, trimesh.Trimesh, trimesh.Trimesh]:
    ref = trimesh.creation.capsule(height=1.3, radius=0.45, count=[24, 24])
    ref.apply_transform(trimesh.transformations.rotation_matrix(0.4, [1, 2, 3]))
    dis = ref.copy()
    rng = np.random.default_rng(3)
    dis.vertices = dis.vertices + rng.normal(0, 0.01, dis.vertices.shape)
    ref_obj, dis_obj = _obj(ref, tmp_path / "ref.obj"), _obj(dis, tmp_path / "dis.obj")
    load = lambda p: trimesh.load(p, process=False)  # noqa: E731
    return ref_obj, dis_obj, load(ref_obj), load(dis_obj)


@pytest.mark.parametrize("use_normal", [True, False])
def test_grid_points_equal_mm_sample(tmp_path: Path, use_normal: bool) -> None:
    _, dis_obj, _, dis = _shapes(tmp_path)
    lo, hi = [-1.1, -0.9, -1.05], [0.95, 1.2, 1.0]  # off-centre box; the noisy mesh may leave it
    args = ["sample", "--mode", "grid", "--gridSize", "96", "--minPos", " ".join(map(str, lo))]
    args += ["--maxPos", " ".join(map(str, hi)), "-i", str(dis_obj), "-o", str(tmp_path / "s.ply"), "--hideProgress"]
    _mm(*args, *(["--useNormal"] if use_normal else []))
    theirs = _read_ply(tmp_path / "s.ply")
    ours = grid_sample(dis, 96, use_normal=use_normal, box=(lo, hi))
    assert ours.num_points == theirs.shape[0]
    assert ours.normals is not None
    # same points, same normals, in the same order (mmetric writes its first occurrences in push order)
    np.testing.assert_array_equal(ours.points.numpy(), theirs[:, :3])
    np.testing.assert_array_equal(ours.normals.numpy(), theirs[:, 3:6])


def test_grid_points_follow_each_faces_first_corner_as_mm_does(tmp_path: Path) -> None:
    # Review L, finding 4: rotating every face's corners of the frames (a,b,c)->(b,c,a) moved a printed MPEG Hausdorff
    # PSNR of evaluate --mpeg in its 4th decimal. The ray-triangle test starts from a face's first corner, so the
    # crossings move by float32 ulps; mm's do the same, point by point, so the figures stay mmetric's.
    _, _, _, dis = _shapes(tmp_path)
    rotated = trimesh.Trimesh(dis.vertices, dis.faces[:, [1, 2, 0]], process=False)
    lo, hi = [-1.1, -0.9, -1.05], [0.95, 1.2, 1.0]
    args = ["sample", "--mode", "grid", "--gridSize", "96", "--useNormal", "--minPos", " ".join(map(str, lo))]
    args += ["--maxPos", " ".join(map(str, hi)), "-o", str(tmp_path / "s.ply"), "--hideProgress"]
    _mm(*args, "-i", str(_obj(rotated, tmp_path / "rot.obj")))
    theirs = _read_ply(tmp_path / "s.ply")
    ours = grid_sample(rotated, 96, use_normal=True, box=(lo, hi))
    assert ours.normals is not None
    np.testing.assert_array_equal(ours.points.numpy(), theirs[:, :3])
    np.testing.assert_array_equal(ours.normals.numpy(), theirs[:, 3:6])
    as_stored = grid_sample(dis, 96, use_normal=True, box=(lo, hi)).points
    assert not torch.equal(as_stored, ours.points)  # the corner order does move the points: mm's choice, kept


def test_mesh_mode_figures_equal_mm_compare(tmp_path: Path) -> None:
    ref_obj, dis_obj, ref, dis = _shapes(tmp_path)
    out = _mm("compare", "--mode", "pcc", "--hausdorff", "--inputModelA", str(ref_obj), "--inputModelB", str(dis_obj))
    r = mpeg_compare(vertex_sample(ref), vertex_sample(dis))
    # every figure as mm prints it (9 significant digits): the merged normals are summed in mm's order
    for ours, label in (
        (r.symmetric.d1_psnr, "mseF,PSNR (p2point)"),
        (r.symmetric.d2_psnr, "mseF,PSNR (p2plane)"),
        (r.ref_to_dis.d1_mse, "mse1      (p2point)"),
        (r.ref_to_dis.d2_mse, "mse1      (p2plane)"),
        (r.dis_to_ref.d1_mse, "mse2      (p2point)"),
        (r.dis_to_ref.d2_mse, "mse2      (p2plane)"),
        (r.symmetric.d1_hausdorff, "h.        (p2point)"),
        (r.symmetric.d2_hausdorff, "h.        (p2plane)"),
    ):
        theirs = re.findall(re.escape(label) + r"\s*:\s*(\S+)", out)[-1]
        assert f"{ours:.9g}" == theirs, (label, ours, theirs)


def test_compare_without_distorted_normals_equals_mm(tmp_path: Path) -> None:
    """A distorted cloud without normals gets the reference's, transferred (dmetric's scaleNormals)."""
    _, _, ref, dis = _shapes(tmp_path)
    a = grid_sample(ref, 64)
    b = grid_sample(dis, 64, box=(a.points.min(0).values.tolist(), a.points.max(0).values.tolist()))
    assert a.normals is not None
    lines_a = [" ".join(f"{v:.9g}" for v in row) for row in torch.cat([a.points, a.normals], 1).tolist()]
    head_a = "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n"
    head_a += "property float nx\nproperty float ny\nproperty float nz\nend_header\n"
    (tmp_path / "a.ply").write_text(head_a.format(len(lines_a)) + "\n".join(lines_a) + "\n")
    lines_b = [" ".join(f"{v:.9g}" for v in row) for row in b.points.tolist()]
    head_b = "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n"
    (tmp_path / "b.ply").write_text(head_b.format(len(lines_b)) + "end_header\n" + "\n".join(lines_b) + "\n")
    out = _mm(
        "compare",
        "--mode",
        "pcc",
        "--hausdorff",
        "--resolution",
        "2.5",
        "--inputModelA",
        str(tmp_path / "a.ply"),
        "--inputModelB",
        str(tmp_path / "b.ply"),
    )
    r = mpeg_compare(a, PointCloud(b.points), peak=2.5)
    for ours, label in ((r.ref_to_dis.d2_mse, "mse1      (p2plane)"), (r.dis_to_ref.d2_mse, "mse2      (p2plane)")):
        theirs = _figure(out, label)
        assert abs(ours - theirs) <= 2e-6 * abs(theirs), (label, ours, theirs)


def _colour_ply(path: Path, verts: np.ndarray, faces: np.ndarray, colors: np.ndarray) -> Path:
    head = f"ply\nformat ascii 1.0\nelement vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
    head += "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    head += f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    body = [f"{x:.9g} {y:.9g} {z:.9g} {r} {g} {b}" for (x, y, z), (r, g, b) in zip(verts, colors, strict=True)]
    body += [f"3 {a} {b} {c}" for a, b, c in faces]
    path.write_text(head + "\n".join(body) + "\n")
    return path


def test_per_vertex_colours_equal_mm(tmp_path: Path) -> None:
    from torchmeshmetric.mpeg import load_textured_mesh, mpeg_metrics

    rng = np.random.default_rng(1)
    m = trimesh.creation.icosphere(2)
    c = (rng.random((len(m.vertices), 3)) * 255).astype(np.uint8)
    c2 = np.clip(c.astype(int) + rng.integers(-20, 20, c.shape), 0, 255).astype(np.uint8)
    ref = _colour_ply(tmp_path / "ref.ply", m.vertices, m.faces, c)
    dis = _colour_ply(tmp_path / "dis.ply", m.vertices * 1.01, m.faces, c2)
    out = _mm("compare", "--mode", "pcc", "--hausdorff", "--inputModelA", str(ref), "--inputModelB", str(dis))
    r = mpeg_metrics(load_textured_mesh(ref), load_textured_mesh(dis), sampling="mesh")
    assert r.symmetric.color_psnr is not None
    for k, ours in enumerate(r.symmetric.color_psnr):
        theirs = float(re.findall(rf"(?<!h\.)c\[{k}\],PSNRF\s*:\s*(\S+)", out)[-1])  # not the Hausdorff line
        assert abs(ours - theirs) <= 0.01
    # grid sampling: mmetric interpolates the vertex colours and writes them rounded to 8 bits
    _mm(
        "sample",
        "--mode",
        "grid",
        "--gridSize",
        "64",
        "--useNormal",
        "-i",
        str(ref),
        "-o",
        str(tmp_path / "s.ply"),
        "--hideProgress",
    )
    theirs = _read_ply(tmp_path / "s.ply")
    t = load_textured_mesh(ref)
    ours_cloud = grid_sample(t.mesh, 64, colors=t.colors)
    assert ours_cloud.colors is not None and ours_cloud.num_points == theirs.shape[0]
    np.testing.assert_array_equal(np.floor(ours_cloud.colors.numpy() + 0.5), theirs[:, 6:9])


def test_obj_vertex_colours_equal_mm(tmp_path: Path) -> None:
    """OBJ ``v x y z r g b`` colours in [0, 1] are read as mmetric reads them (scaled to 8 bits)."""
    from torchmeshmetric.mpeg import load_textured_mesh, mpeg_metrics

    rng = np.random.default_rng(2)
    m = trimesh.creation.icosphere(1)
    paths = []
    for name, scale in (("ref.obj", 1.0), ("dis.obj", 1.02)):
        c = rng.integers(0, 256, (len(m.vertices), 3)) / 255.0
        lines = [
            f"v {x:.9g} {y:.9g} {z:.9g} {r:.9g} {g:.9g} {b:.9g}"
            for (x, y, z), (r, g, b) in zip(m.vertices * scale, c, strict=True)
        ]
        lines += [f"f {a + 1} {b + 1} {d + 1}" for a, b, d in m.faces]
        (tmp_path / name).write_text("\n".join(lines) + "\n")
        paths.append(tmp_path / name)
    out = _mm("compare", "--mode", "pcc", "--inputModelA", str(paths[0]), "--inputModelB", str(paths[1]))
    r = mpeg_metrics(load_textured_mesh(paths[0]), load_textured_mesh(paths[1]), sampling="mesh")
    assert r.symmetric.color_psnr is not None
    for k, ours in enumerate(r.symmetric.color_psnr):
        theirs = float(re.findall(rf"(?<!h\.)c\[{k}\],PSNRF\s*:\s*(\S+)", out)[-1])
        assert abs(ours - theirs) <= 0.01
