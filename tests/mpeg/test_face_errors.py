"""Per-face CTC errors: a float64 reference of the grouping (scipy kd-tree), locality, the writers and the command."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import torch

from torchmeshmetric.cli import main
from torchmeshmetric.mpeg.core.point_cloud import merge_duplicate_points
from torchmeshmetric.mpeg.core.reindex import oriented_reindex
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.mpeg.ctc.chain import _dequantized
from torchmeshmetric.mpeg.ctc.face_errors import ctc_face_errors, write_face_errors_csv, write_face_errors_ply
from torchmeshmetric.mpeg.sampling.grid_sampling import grid_sample, grid_sample_faces
from torchmeshmetric.structures import Mesh

BOX = ([-1.0, -1.0, -1.0], [1.0, 1.0, 1.0])


def _pair() -> tuple[TexturedMesh, TexturedMesh, int]:
    """A quantised icosphere and a decoded copy with one vertex moved 30 steps outward; that vertex's index."""
    import trimesh

    s = trimesh.creation.icosphere(1)
    q = np.round((s.vertices * 0.8 + 1) * 511.5)
    d = q.copy()
    d[7] += np.round(s.vertices[7] * 30)
    f = torch.tensor(s.faces)
    return TexturedMesh(Mesh(torch.tensor(q), f)), TexturedMesh(Mesh(torch.tensor(d), f)), 7


def test_decoded_side_equals_a_brute_force_reference() -> None:
    """Each decoded face: mean and max over its samples of the squared distance to the nearest merged source sample."""
    ref, dis, _ = _pair()
    e = ctc_face_errors(ref, dis, qp=10, qt=0, min_pos=BOX[0], max_pos=BOX[1], grid_size=64)
    r = oriented_reindex(_dequantized(ref, 10, 0, BOX, "ref", "qt"))
    d = oriented_reindex(_dequantized(dis, 10, 0, BOX, "dis", "qt"))
    assert torch.equal(e.mesh.faces, d.mesh.faces)
    target = merge_duplicate_points(grid_sample(r.mesh, 64, box=BOX, use_fixed_point=True)).points.numpy()
    mine = grid_sample_faces(d.mesh, 64, box=BOX, use_fixed_point=True)
    pts = mine.cloud.points.numpy().astype(np.float64)
    from scipy.spatial import cKDTree

    nearest = cKDTree(target.astype(np.float64)).query(pts)[1]
    sq = ((pts - target[nearest].astype(np.float64)) ** 2).sum(1)  # float64 from the float32 points
    for face in range(e.samples.shape[0]):
        own = sq[mine.face_idx == face]
        assert e.samples[face] == own.size
        if own.size:
            assert e.d1_mean[face] == pytest.approx(own.mean(), rel=1e-6, abs=1e-12)
            assert e.d1_max[face] == pytest.approx(own.max(), rel=1e-6, abs=1e-12)
        else:
            assert np.isnan(e.d1_mean[face]) and np.isnan(e.d2_max[face])
    assert e.color_mean is None


def test_errors_sit_on_the_moved_vertex_faces() -> None:
    """Faces away from the moved vertex sample exactly the source's points (0); faces around it carry the error."""
    ref, dis, moved = _pair()
    for side in ("decoded", "source"):
        e = ctc_face_errors(ref, dis, qp=10, qt=0, min_pos=BOX[0], max_pos=BOX[1], grid_size=64, side=side)
        verts = e.mesh.verts.numpy()
        src = (ref if side == "source" else dis).mesh.verts.numpy()[moved]
        gap = np.linalg.norm(verts - ((src / 1023) * 2 - 1), axis=1)  # the fixed-point scale: within 0.02
        at = int(np.argmin(gap))
        assert gap[at] < 0.02 and np.sort(gap)[1] > 0.2
        touching = (e.mesh.faces.numpy() == at).any(1)
        sampled = e.samples > 0
        assert np.all(e.d1_max[~touching & sampled] == 0) and touching.sum() == 5
        assert np.nanmin(e.d1_max[touching]) > 0


def test_writers_and_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """PLY (face properties, colours) and CSV agree; the command writes both, refuses to overwrite, checks options."""
    ref, dis, _ = _pair()
    e = ctc_face_errors(ref, dis, qp=10, qt=0, min_pos=BOX[0], max_pos=BOX[1], grid_size=64)
    write_face_errors_ply(tmp_path / "a.ply", e)
    write_face_errors_csv(tmp_path / "a.csv", e)
    data = (tmp_path / "a.ply").read_bytes()
    head, body = data.split(b"end_header\n", 1)
    assert b"property double d2_max" in head and b"element face 80" in head
    nv = e.mesh.verts.shape[0]
    dtype = np.dtype(
        [
            ("n", "u1"),
            ("idx", "<i4", 3),
            ("rgb", "u1", 3),
            ("samples", "<i4"),
            ("d1_mean", "<f8"),
            ("d1_max", "<f8"),
            ("d2_mean", "<f8"),
            ("d2_max", "<f8"),
        ]
    )
    faces = np.frombuffer(body[nv * 12 :], dtype)
    assert faces.shape[0] == 80 and np.array_equal(faces["idx"], e.mesh.faces.numpy())
    np.testing.assert_array_equal(faces["d1_max"], e.d1_max)
    with (tmp_path / "a.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["d1_mean"]) for r in rows] == e.d1_mean.tolist()
    with pytest.raises(ValueError, match="color_by: expected one of"):
        write_face_errors_ply(tmp_path / "b.ply", e, color_by="y_mean")
    for name, m in (("src.obj", ref), ("dec.obj", dis)):
        v, f = m.mesh.verts.numpy(), m.mesh.faces.numpy()
        lines = [f"v {a:.0f} {b:.0f} {c:.0f}" for a, b, c in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
        (tmp_path / name).write_text("\n".join(lines) + "\n")
    args = [
        "ctc-face-errors",
        "--reference",
        str(tmp_path / "src.obj"),
        "--decoded",
        str(tmp_path / "dec.obj"),
        "--qp",
        "10",
        "--qt",
        "0",
        "--min-pos",
        "-1 -1 -1",
        "--max-pos",
        "1 1 1",
        "--grid-size",
        "64",
        "--out",
        str(tmp_path / "cmd"),
    ]
    assert main(args) == 0
    assert (tmp_path / "cmd.csv").read_bytes() == (tmp_path / "a.csv").read_bytes()
    assert (tmp_path / "cmd.ply").read_bytes() == data
    assert main(args) == 1
    assert "already exists (pass --overwrite" in capsys.readouterr().err
    assert main([*args, "--overwrite", "--color-by", "y_mean"]) == 1
    assert "--color-by y_mean: the frames have no colour" in capsys.readouterr().err
    assert main([*args[:-1], str(tmp_path / "x"), "--qp", "3"]) == 1
    assert "--qp: expected an integer in 7..31, found 3" in capsys.readouterr().err
    # review X, F8: --out OUT.ply wrote OUT.ply.ply and OUT.ply.csv; it names the PLY now (OUT the stem, as before)
    assert main([*args[:-1], str(tmp_path / "named.ply")]) == 0
    assert (tmp_path / "named.ply").read_bytes() == data and (tmp_path / "named.csv").is_file()
    assert not (tmp_path / "named.ply.ply").exists()
