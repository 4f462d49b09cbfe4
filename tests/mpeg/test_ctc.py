"""The CTC chain (dequantise, oriented reindex, fixed-point grid sampling, compare, clipped means) against ``mm``.

Sequences are built here: the built-in demo sequence's frames quantised with ``mm quantize`` (source) and a
distorted copy in the same integer space (decoded), and the textured torus of ``../shared/reference/mpeg``
quantised with UVs. ``mm sequence`` runs the test model's chain on them (scripts/run.sh's ``mmpsnr_pcc``) and its
printed figures are the oracle. mmetric prints 9 significant digits; on every sequence tried (3-frame demo at grid
1024, the textured torus) our figures equal its printed values to all digits, so the tolerance is one unit of the
9th digit of a ~100 dB figure (1e-6 dB).
"""

from __future__ import annotations

import math
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
import torch

from tests.mpeg.conftest import MM, MPEG_REF
from torchmeshmetric.mpeg.core.reindex import oriented_reindex
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh, load_textured_mesh
from torchmeshmetric.mpeg.ctc.chain import CTC_COLUMNS, CtcSequence, ctc_mean, ctc_sequence
from torchmeshmetric.mpeg.ctc.dequantize import dequantize_positions, dequantize_uvs, position_scale
from torchmeshmetric.mpeg.sampling import grid_sampling as gs
from torchmeshmetric.structures import Mesh

MM_BIN = MM
needs_mm = pytest.mark.skipif(not MM_BIN.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
TOL_DB = 1e-6


def _write_obj(path: Path, v: np.ndarray, f: np.ndarray, fmt: str = ".9g") -> None:
    lines = ["v " + " ".join(format(x, fmt) for x in p) for p in v]
    lines += ["f " + " ".join(str(int(i) + 1) for i in t) for t in f]
    path.write_text("\n".join(lines) + "\n")


def _box_args(lo: np.ndarray, hi: np.ndarray) -> list[str]:
    return ["--minPos", " ".join(f"{x:.9g}" for x in lo), "--maxPos", " ".join(f"{x:.9g}" for x in hi)]


def _mm(*args: str, cwd: Path) -> str:
    out = subprocess.run([str(MM_BIN), *args], cwd=cwd, capture_output=True, text=True, timeout=900)
    return out.stdout + out.stderr


def _mm_chain(cwd: Path, n: int, qp: int, qt: int, box: tuple[np.ndarray, np.ndarray], res: float, grid: int,
              textured: bool, ibsm: tuple[int, int] | None = None) -> str:  # fmt: skip
    """``mm sequence`` runs of the test model (scripts/run.sh): ``mmpsnr_seq`` + ``mmpsnr_pcc``, and ``mmpsnr_ibsm``."""
    b = _box_args(*box)
    uv = ["--minUv", "0 0", "--maxUv", "1.0 1.0"]
    samp = ["--mode", "grid", "--gridSize", str(grid), "--hideProgress", "--useNormal", "--useFixedPoint", *b]
    seq = ["sequence", "--firstFrame", "0", "--lastFrame", str(n - 1), "END"]
    seq += ["dequantize", "--inputModel", "src_%04d.obj", "--outputModel", "ID:deqRef", "--useFixedPoint",
            "--qp", str(qp), *b, "--qt", str(qt), *uv, "END"]  # fmt: skip
    seq += ["dequantize", "--inputModel", "dec_%04d.obj", "--outputModel", "ID:deqDis", "--useFixedPoint",
            "--qp", str(qp), *b, "--qt", "0", *uv, "END"]  # fmt: skip
    args = list(seq)
    for name, out in (("Ref", "pcRef"), ("Dis", "pcDis")):
        tex = ["-m", ("src" if name == "Ref" else "dec") + "_%04d.png"] if textured else []
        args += ["reindex", "--sort", "oriented", "-i", f"ID:deq{name}", "-o", "ID:reordered", "END"]
        args += ["sample", *samp, "--bilinear", "-i", "ID:reordered", *tex, "-o", f"ID:{out}", "END"]
    args += ["compare", "--mode", "pcc", "--resolution", f"{res:.9g}", "--inputModelA", "ID:pcRef",
             "--inputModelB", "ID:pcDis"]  # fmt: skip
    log = _mm(*args, cwd=cwd)
    if ibsm is not None:
        maps = ["--inputMapA", "src_%04d.png", "--inputMapB", "dec_%04d.png"] if textured else []
        log += _mm(*seq, "compare", "--mode", "ibsm", "--inputModelA", "ID:deqRef", "--inputModelB", "ID:deqDis",
                   *maps, "--ibsmResolution", str(ibsm[0]), "--ibsmCameraCount", str(ibsm[1]), cwd=cwd)  # fmt: skip
    return log


def _parse(log: str) -> tuple[list[dict[str, float]], dict[str, float]]:
    """Per-frame symmetric figures and the sequence means mmetric prints."""
    names = {"p2point": "GridD1", "p2plane": "GridD2"}
    frames: list[dict[str, float]] = []
    for line in log.splitlines():
        m = re.match(r"\s*mseF,PSNR \((p2point|p2plane)\): (\S+)", line)
        if m:
            if m.group(1) == "p2point":
                frames.append({})
            frames[-1][names[m.group(1)]] = float(m.group(2))
        m = re.match(r"\s*c\[(\d)\],PSNRF\s*: (\S+)", line)
        if m:
            frames[-1][("GridLuma", "GridChromaCb", "GridChromaCr")[int(m.group(1))]] = float(m.group(2))
        m = re.match(r"(GEO|Y  ) PSNR = (\S+)", line)  # the IBSM run comes after the grid run: frames in order
        if m:
            col = "IbsmGeom" if m.group(1) == "GEO" else "IbsmLuma"
            k = next(i for i, f in enumerate(frames) if col not in f)
            frames[k][col] = float(m.group(2))
    means = {}
    for key, col in (("mseF, PSNR\\(p2point\\)", "GridD1"), ("mseF, PSNR\\(p2plane\\)", "GridD2"),
                     ("c\\[0\\],PSNRF", "GridLuma"), ("c\\[1\\],PSNRF", "GridChromaCb"),
                     ("c\\[2\\],PSNRF", "GridChromaCr"), ("GEO PSNR ", "IbsmGeom"),
                     ("Y   PSNR ", "IbsmLuma")):  # fmt: skip
        m = re.search(key + r"\s*Mean=(\S+)", log)
        if m:
            means[col] = float(m.group(1))
    return frames, means


def _assert_equal(ours: CtcSequence, log: str) -> None:
    frames, means = _parse(log)
    assert len(frames) == len(ours.frames)
    for f_mm, f in zip(frames, ours.frames, strict=True):
        assert set(f_mm) == set(f.figures)
        for k, v in f_mm.items():
            if math.isinf(v):
                assert math.isinf(f.figures[k])
            else:
                assert abs(f.figures[k] - v) <= TOL_DB, (f.frame, k, f.figures[k], v)
    mean = ours.mean()
    for k, v in means.items():
        if k not in frames[0]:  # mmetric prints a mean of 0 for colour figures it did not compute
            assert v == 0 and k not in mean
            continue
        assert abs(mean[k] - v) <= TOL_DB, (k, mean[k], v)


@pytest.fixture(scope="module")
def demo_seq(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, tuple[np.ndarray, np.ndarray]]:
    """Two demo frames quantised to 12 bits by ``mm quantize``; decoded = simplified + noisy integer copies."""
    if not MM_BIN.is_file():
        pytest.skip("mm absent")
    import fast_simplification

    from torchmeshmetric.data import demo_sequence

    d = tmp_path_factory.mktemp("ctc_demo")
    seq = demo_sequence(2, resolution=64)
    allv = np.concatenate([fr.verts.numpy() for fr in seq.frames])
    lo, hi = allv.min(0).astype(np.float32), allv.max(0).astype(np.float32)
    rng = np.random.default_rng(0)
    for i, fr in enumerate(seq.frames):
        _write_obj(d / f"raw_{i:04d}.obj", fr.verts.numpy(), fr.faces.numpy())
        _mm("quantize", "-i", f"raw_{i:04d}.obj", "-o", f"src_{i:04d}.obj", "--qp", "12", "--qt", "0", "--qn", "0",
            "--qc", "0", *_box_args(lo, hi), cwd=d)  # fmt: skip
        q = load_textured_mesh(d / f"src_{i:04d}.obj").mesh
        v2, f2 = fast_simplification.simplify(q.verts.numpy(), q.faces.numpy().astype(np.int32), 0.4 + 0.2 * i)
        v2 = np.round(v2 + rng.normal(0, 1.5, v2.shape)).clip(0, 4095)
        # frame 1 keeps a few vertices beyond the box (a decoded frame may leave it): mmetric samples them
        if i == 1:
            v2[:5] += 40
        _write_obj(d / f"dec_{i:04d}.obj", v2, f2, ".0f")
    return d, (lo, hi)


@needs_mm
def test_dequantize_equals_mm(demo_seq: tuple[Path, tuple[np.ndarray, np.ndarray]]) -> None:
    """Fixed-point dequantisation is bit-identical to ``mm dequantize --useFixedPoint`` (its 9-digit OBJ output)."""
    d, (lo, hi) = demo_seq
    _mm("dequantize", "-i", "dec_0000.obj", "-o", "deq.obj", "--useFixedPoint", "--qp", "12", *_box_args(lo, hi),
        "--qt", "0", cwd=d)  # fmt: skip
    ours = dequantize_positions(load_textured_mesh(d / "dec_0000.obj").mesh.verts, 12, lo, hi)
    theirs = load_textured_mesh(d / "deq.obj").mesh.verts.to(torch.float32)
    assert torch.equal(ours, theirs)


@needs_mm
def test_demo_sequence_chain_equals_mm(demo_seq: tuple[Path, tuple[np.ndarray, np.ndarray]]) -> None:
    """Untextured 2-frame sequence at grid 512, IBSM 512 x 8 (a decoded frame leaves the box): every figure, mean."""
    d, (lo, hi) = demo_seq
    res = float(np.max(hi - lo))
    log = _mm_chain(d, 2, 12, 0, (lo, hi), res, 512, textured=False, ibsm=(512, 8))
    pairs = (
        (i, load_textured_mesh(d / f"src_{i:04d}.obj"), load_textured_mesh(d / f"dec_{i:04d}.obj")) for i in range(2)
    )
    ours = ctc_sequence(pairs, qp=12, qt=0, min_pos=lo, max_pos=hi, resolution=res, grid_size=512,
                        ibsm_resolution=512, ibsm_cameras=8)  # fmt: skip
    assert ours.columns == ("GridD1", "GridD2", "IbsmGeom", "IbsmLuma")
    _assert_equal(ours, log)


@needs_mm
def test_textured_chain_equals_mm(tmp_path: Path) -> None:
    """Textured torus: source quantised with UVs (qt 10), decoded = the coarse torus (float UVs) and the source
    with a noisy texture (geometry identical: D1 inf, clipped to 99.99 in the mean)."""
    t = MPEG_REF / "textured"
    if not t.is_dir():
        pytest.skip("../shared/reference/mpeg absent")
    lo, hi = np.array([-1.36, -1.36, -0.36], np.float32), np.array([1.36, 1.36, 0.36], np.float32)
    q = ["--qn", "0", "--qc", "0", *_box_args(lo, hi), "--minUv", "0 0", "--maxUv", "1 1"]
    _mm("quantize", "-i", str(t / "ref.obj"), "-o", "src_0000.obj", "--qp", "11", "--qt", "10", *q, cwd=tmp_path)
    _mm("quantize", "-i", str(t / "coarse.obj"), "-o", "dec_0000.obj", "--qp", "11", "--qt", "0", *q, cwd=tmp_path)
    _mm("dequantize", "-i", "src_0000.obj", "-o", "dec_0001.obj", "--qp", "0", "--qt", "10", "--minUv", "0 0",
        "--maxUv", "1 1", cwd=tmp_path)  # fmt: skip
    (tmp_path / "src_0001.obj").write_bytes((tmp_path / "src_0000.obj").read_bytes())
    for name, src in (("src_0000", "texture"), ("src_0001", "texture"), ("dec_0000", "texture"),
                      ("dec_0001", "texture_noisy")):  # fmt: skip
        (tmp_path / f"{name}.png").write_bytes((t / f"{src}.png").read_bytes())
    for p in tmp_path.glob("*.obj"):  # the textures are named explicitly (the MTLs are not copied)
        p.write_text("".join(line for line in p.read_text().splitlines(True) if not line.startswith("mtllib")))
    log = _mm_chain(tmp_path, 2, 11, 10, (lo, hi), 2.72, 256, textured=True, ibsm=(400, 5))
    pairs = (
        (i, load_textured_mesh(tmp_path / f"src_{i:04d}.obj", tmp_path / f"src_{i:04d}.png"),
         load_textured_mesh(tmp_path / f"dec_{i:04d}.obj", tmp_path / f"dec_{i:04d}.png"))
        for i in range(2)
    )  # fmt: skip
    ours = ctc_sequence(pairs, qp=11, qt=10, min_pos=lo, max_pos=hi, resolution=2.72, grid_size=256,
                        ibsm_resolution=400, ibsm_cameras=5)  # fmt: skip
    assert ours.columns == CTC_COLUMNS
    assert math.isinf(ours.frames[1].figures["GridD1"])
    _assert_equal(ours, log)


def test_fixed_point_rounding() -> None:
    """Box corners outward and the scale upward to multiples of 1/65536; exact in float32."""
    lo, scale = position_scale(12, [-0.3, 0.1, 0.0], [0.7, 1.2, 0.5])
    assert (lo * 65536).tolist() == [math.floor(np.float32(-0.3) * 65536), math.floor(np.float32(0.1) * 65536), 0.0]
    assert scale * 65536 == math.ceil(np.float32(np.float32(1.1000977) / np.float32(4095)) * 65536)
    assert float(np.float32(scale)) == scale
    with pytest.raises(ValueError, match="qp"):
        position_scale(40, [0, 0, 0], [1, 1, 1])
    with pytest.raises(ValueError, match="max_pos"):
        position_scale(12, [0, 0, 0], [1, -1, 1])
    assert dequantize_uvs(torch.tensor([[1023.0, 0.0]]), 10).tolist() == [[1.0, 0.0]]
    assert dequantize_uvs(torch.tensor([[5.0, 7.0]]), 0).tolist() == [[5.0, 7.0]]  # below 7: unchanged


def test_ctc_mean_clips_like_mmetric() -> None:
    """mmetric's mean: (1/n)-weighted sum of min(psnr, 99.99)."""
    assert ctc_mean([40.0, math.inf, 60.0]) == pytest.approx((40 + 99.99 + 60) / 3, abs=1e-12)
    assert ctc_mean([120.0]) == 99.99


def test_oriented_reindex_keeps_surface() -> None:
    """Same triangles (as sets of positions) after reindexing, duplicates and rotations gone, orientation kept."""
    v = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    f = torch.tensor([[2, 0, 1], [0, 1, 2], [1, 3, 2]])
    r = oriented_reindex(TexturedMesh(Mesh(v, f)))
    tris = {tuple(map(tuple, r.mesh.verts[t].tolist())) for t in r.mesh.faces}
    assert len(tris) == 2
    n_in = torch.linalg.cross(v[1] - v[0], v[2] - v[0])
    for t in r.mesh.faces:
        p = r.mesh.verts[t]
        assert torch.dot(torch.linalg.cross(p[1] - p[0], p[2] - p[0]), n_in) > 0


@pytest.mark.parametrize("chunk", [1, 7, 1000])
def test_grid_chunks_split_entries(monkeypatch: pytest.MonkeyPatch, chunk: int) -> None:
    """Ray chunks that split one triangle's rays give the same hits in the same order as one chunk (numpy path)."""
    monkeypatch.setattr(gs, "_USE_NATIVE", False)
    import trimesh

    s = trimesh.creation.icosphere(1)
    mesh = (torch.tensor(s.vertices), torch.tensor(s.faces))
    box = ([-1.0, -1.0, -1.0], [1.0, 1.0, 1.0])
    whole = gs.grid_hits(mesh, 40, box=box, use_fixed_point=True)
    monkeypatch.setattr(gs, "_CHUNK", chunk)
    parts = gs.grid_hits(mesh, 40, box=box, use_fixed_point=True)
    for a, b in zip(whole, parts, strict=True):
        np.testing.assert_array_equal(a, b)


def test_grid_too_large_refused_up_front() -> None:
    """A grid whose samples cannot fit is refused before casting, naming --grid-size and the estimate."""
    import trimesh

    s = trimesh.creation.icosphere(1)
    with pytest.raises(gs.GridTooLargeError, match=r"grid_size \(--grid-size\) 10000000: .* about [0-9.e+]+ points"):
        gs.grid_sample((torch.tensor(s.vertices), torch.tensor(s.faces)), 10_000_000)


def test_estimated_hits_close_to_actual() -> None:
    """The up-front estimate (projected areas / step^2) is within 1 % of the hits (measured: 0.2 % on the torus)."""
    import trimesh

    s = trimesh.creation.torus(1.0, 0.35)
    mesh = (torch.tensor(s.vertices), torch.tensor(s.faces))
    v, f = gs.mesh_arrays(mesh)
    lo, hi = gs.mesh_box(v)
    step = np.full(3, (hi - lo).max() * (np.float32(1) / np.float32(255)), np.float32)
    est = gs._estimated_hits(gs._entries(v, f, lo, hi, step, True), step)
    hits = gs.grid_hits(mesh, 256).points.shape[0]
    assert abs(est - hits) < 0.01 * hits


def _unique_based(corner_keys: np.ndarray) -> np.ndarray:
    """The reorder through np.unique (what the mesh mode used when it was checked against mm)."""
    _, first, inverse = np.unique(corner_keys, axis=0, return_index=True, return_inverse=True)
    tri = inverse.reshape(-1)[np.arange(corner_keys.shape[0]).reshape(-1, 3)]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    rot1 = (b < a) & (b <= c)
    rot2 = ~rot1 & (c <= a) & (c < b)
    out = tri.copy()
    out[rot1] = np.stack([b, c, a], axis=1)[rot1]
    out[rot2] = np.stack([c, a, b], axis=1)[rot2]
    return first[np.unique(out, axis=0)]


def test_oriented_faces_equals_the_unique_based_reorder() -> None:
    """The lexsort reorder equals an np.unique one (validated against mm), -0.0 and repeats too."""
    from torchmeshmetric.mpeg.core.reindex import oriented_faces

    rng = np.random.default_rng(0)
    for trial in range(200):
        nv, nf = int(rng.integers(3, 30)), int(rng.integers(1, 40))
        v = rng.integers(-3, 4, (nv, 3)).astype(np.float32)
        v[v == 0] = np.where(rng.random(int((v == 0).sum())) < 0.5, -0.0, 0.0).astype(np.float32)
        f = rng.integers(0, nv, (nf, 3))
        if trial % 3 == 0:  # repeated and rotated faces
            f = np.concatenate([f, f[:, [1, 2, 0]], f])
        keys = v[f].reshape(-1, 3)
        if trial % 2:  # UV keys
            keys = np.concatenate([keys, rng.integers(0, 3, (keys.shape[0], 2)).astype(np.float32)], axis=1)
        np.testing.assert_array_equal(oriented_faces(keys), _unique_based(keys))


@pytest.mark.parametrize(
    ("grid", "box", "use_normal", "fixed"),
    [(97, ([-1, -1, 0], [1, 1, 0]), True, True), (50, ([-1, -1, -1], [1, 1, 1]), False, False), (64, None, True, False),
     (300, ([-1.2, -1, -1], [1, 1.3, 1]), False, True)],
)  # fmt: skip
def test_native_grid_caster_equals_numpy(
    monkeypatch: pytest.MonkeyPatch, grid: int, box: tuple | None, use_normal: bool, fixed: bool
) -> None:
    """The C++ ray caster gives the numpy path's hits, bit for bit and in the same order (flat box, all axes too)."""
    import trimesh

    s = trimesh.creation.icosphere(2)
    mesh = (torch.tensor(s.vertices * [1.0, 0.7, 1.2]), torch.tensor(s.faces))
    native = gs.grid_hits(mesh, grid, box=box, use_normal=use_normal, use_fixed_point=fixed)
    monkeypatch.setattr(gs, "_USE_NATIVE", False)
    reference = gs.grid_hits(mesh, grid, box=box, use_normal=use_normal, use_fixed_point=fixed)
    assert native.points.shape[0] > 0
    for a, b in zip(native, reference, strict=True):
        np.testing.assert_array_equal(a, b)
