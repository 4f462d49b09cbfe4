"""What the ``*_sampling_against_mm`` tests share: running ``mm sample``, the library's input and rows, a demo frame."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np

from tests.mpeg.conftest import MM
from torchmeshmetric.mpeg import PointCloud, TexturedMesh, load_textured_mesh
from torchmeshmetric.mpeg.core._float32 import roundf


def mm_sample(obj: Path, texture: Path | None, tmp_path: Path, mode: str, *options: str) -> np.ndarray:
    """The rows ``(x y z nx ny nz [r g b])`` of ``mm sample --mode MODE OPTIONS`` on ``obj`` (``-m`` ``texture``)."""
    out = tmp_path / "mm.ply"
    args = [str(MM), "sample", "--mode", mode, *options, "-i", str(obj), "-o", str(out), "--hideProgress"]
    args += ["-m", str(texture) if texture else ""]
    subprocess.run(args, capture_output=True, text=True, timeout=300, check=True)
    with open(out) as fh:
        for line in fh:
            if line.startswith("end_header"):
                break
        return np.loadtxt(fh, dtype=np.float64, ndmin=2)


def library_mesh(obj: Path, texture: Path | None) -> TexturedMesh:
    """The mesh as mm sees it: without a map given (``texture`` ``None``) only per-vertex colours count."""
    mesh = load_textured_mesh(obj, texture)
    return mesh if texture is not None else TexturedMesh(mesh.mesh, None, None, mesh.colors)


def assert_same_rows_in_order(pc: PointCloud, theirs: np.ndarray) -> int:
    """Same points and normals in the same order (float32), and mm's colour bytes (``roundf``); the row count."""
    ours = np.concatenate([pc.points.numpy(), pc.normals.numpy()], axis=1)
    assert ours.shape == theirs[:, :6].shape
    np.testing.assert_array_equal(ours, theirs[:, :6].astype(np.float32))  # same points, same order
    if pc.colors is not None:
        assert theirs.shape[1] == 9
        np.testing.assert_array_equal(roundf(pc.colors.numpy()), theirs[:, 6:])  # mm writes roundf(c)
    else:
        assert theirs.shape[1] == 6
    return ours.shape[0]


def _sorted_rows(a: np.ndarray) -> np.ndarray:
    return a[np.lexsort(a.T[::-1])]


def assert_same_rows_sorted(pc: PointCloud, data: np.ndarray) -> int:
    """The same rows bit for bit (positions and normals in float32, mm's colour bytes) as sorted arrays; the count."""
    theirs = np.concatenate([data[:, :6].astype(np.float32).astype(np.float64), data[:, 6:]], axis=1)
    cols = [pc.points.numpy(), pc.normals.numpy()]
    if pc.colors is not None:
        cols.append(roundf(pc.colors.numpy()))  # mm writes roundf(colour)
    ours = np.concatenate(cols, axis=1).astype(np.float64)
    assert ours.shape == theirs.shape
    np.testing.assert_array_equal(_sorted_rows(ours), _sorted_rows(theirs))
    return ours.shape[0]


def demo_frame_obj(tmp_path: Path) -> tuple[Path, int, int]:
    """A demo frame (resolution 48) written as ``frame.obj`` (float32 positions, ``%.9g``): path, vertices, faces."""
    from torchmeshmetric.data import demo_sequence

    frame = demo_sequence(1, resolution=48).frames[0]
    v, f = frame.verts.float().numpy(), frame.faces.numpy()
    obj = tmp_path / "frame.obj"
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    obj.write_text("\n".join(lines) + "\n")
    return obj, len(v), len(f)
