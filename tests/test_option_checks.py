"""Review V (eleventh round): options and helper inputs refused with a typed error naming the argument.

F10 (unclear errors), F11 (truthy strings taken as flags), F14 (numpy integers refused by hand-rolled checks), F5/F9
(statistics helpers). Each case failed before with an untyped torch/numpy error, a message naming another argument,
or no error at all.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
import torch
import trimesh

import torchmeshmetric as t
from torchmeshmetric._checks import DeviceError, IndexRangeError, NonFiniteError, ShapeError, SizeLimitError
from torchmeshmetric.data import add_capture_defects
from torchmeshmetric.evaluation import evaluate_pair, mean_statistics, paired_t_interval
from torchmeshmetric.stats import DistanceAccumulator, linear_quantiles, merge_moments, moments_of, psnr_from_mse
from torchmeshmetric.tasks import shard
from torchmeshmetric.temporal.registered import weld_short_edges
from torchmeshmetric.temporal.topology import mesh_edges

_S = trimesh.creation.icosphere(subdivisions=1)
V = torch.tensor(_S.vertices)
F = torch.tensor(_S.faces)
M = t.Mesh(V, F)
D = torch.linspace(0.01, 1.0, 11, dtype=torch.float64)
_P32 = np.asarray(_S.vertices, np.float32)
_TEX = np.zeros((2, 2, 3), np.uint8)


def _pair(**kw: Any) -> Any:
    return evaluate_pair(M, M, M, precomputed_registration=kw.pop("precomputed_registration", M), **kw)


CASES: list[tuple[str, Callable[[], Any], type[Exception], str]] = [
    # F14 / F10: sample_surface's n, generator
    ("n float", lambda: t.sample_surface(V, F, 1.5), TypeError, "n: expected an int, found float 1.5"),
    ("n str", lambda: t.sample_surface(V, F, "10"), TypeError, "n: expected an int, found str '10'"),
    ("n bool", lambda: t.sample_surface(V, F, True), TypeError, "n: expected an int, found bool True"),
    ("n negative", lambda: t.sample_surface(V, F, -1), ValueError, "n: expected an int >= 0, found -1"),
    ("n per mesh", lambda: t.sample_surface(V, F, [1, 2]), ValueError, r"n: expected an int or 1 ints \(one per"),
    (
        "n huge",
        lambda: t.sample_surface(V, F, 10**15),
        SizeLimitError,
        r"n: 1000000000000000 asks for about 1e\+15 samples",
    ),
    (
        "generator seed",
        lambda: t.sample_surface(V, F, 10, generator=0),
        TypeError,
        "generator: expected a torch.Generator or None, found int 0",
    ),
    # F10: seeds, caches, names
    (
        "seed range",
        lambda: t.mesh_surface_distance_loss((V, F), (V, F), surface_samples=10, seed=2**70),
        ValueError,
        r"seed: expected an int in \[-2\*\*63, 2\*\*64\)",
    ),
    (
        "indexes dict",
        lambda: t.mesh_surface_distance_loss(V[:3], (V, F), indexes={}),
        TypeError,
        "indexes: expected an IndexCache or None, found dict",
    ),
    (
        "indexes dict (vertex)",
        lambda: t.nearest_vertex_distance_loss(V[:3], (V, F), indexes={}),
        TypeError,
        "indexes: expected an IndexCache or None, found dict",
    ),
    ("registration str", lambda: _pair(precomputed_registration="x"), TypeError, "^precomputed_registration: "),
    ("device", lambda: _pair(device="nope"), DeviceError, "device: 'nope' is not a device"),
    ("defects seed", lambda: add_capture_defects(M, seed="a"), TypeError, "seed: expected an int, found str 'a'"),
    (
        "defects fraction",
        lambda: add_capture_defects(M, duplicate_fraction="a"),
        TypeError,
        "duplicate_fraction: expected a float",
    ),
    (
        "lengths list",
        lambda: t.point_mesh_distance(V[:4], V, F, points_lengths=[4]),
        TypeError,
        "points_lengths: expected a torch.Tensor, found list",
    ),
    (
        "lengths float",
        lambda: t.point_mesh_distance(V[:4], V, F, points_lengths=torch.tensor([4.0])),
        TypeError,
        "points_lengths: expected an integer tensor, found dtype torch.float32",
    ),
    (
        "sets count",
        lambda: t.point_mesh_distance([V[:2], V[:3]], [(V, F)]),
        ValueError,
        r"^points: expected 1 point sets \(one per mesh\), found 2",
    ),
    (
        "no vertices",
        lambda: t.point_mesh_distance(V[:3], V[:0], F),
        IndexRangeError,
        r"faces: found vertex indices in \[0, 41\], but the vertices are empty",
    ),
    ("merge dim", lambda: merge_moments(moments_of(D), dim=5), IndexRangeError, "dim: expected a dimension"),
    (
        "confidence",
        lambda: paired_t_interval([1.0, 2.0, 3.0], confidence=0.0),
        ValueError,
        r"confidence: expected a coverage in \(0, 1\), found 0.0",
    ),
    (
        "nan differences",
        lambda: paired_t_interval([1.0, float("nan")]),
        ValueError,
        "differences: expected finite differences, found 1 NaN/Inf",
    ),
    ("shard world 0", lambda: shard(10, 0, 0), ValueError, "world_size: expected an int >= 1, found 0"),
    ("shard rank", lambda: shard(10, 3, 2), ValueError, r"rank: expected a rank in \[0, 1\]"),
    ("shard rank -1", lambda: shard(10, -1, 2), ValueError, "rank: expected an int >= 0, found -1"),
    ("shard tasks", lambda: shard(-1, 0, 1), ValueError, "num_tasks: expected an int >= 0, found -1"),
    ("weld name", lambda: weld_short_edges(M, 10.0), ValueError, "^fraction: expected a fraction"),
    ("mesh_edges range", lambda: mesh_edges(F, 10), IndexRangeError, r"faces: expected vertex indices in \[0, 9\]"),
    (
        "nonrigid generator",
        lambda: t.register_nonrigid(M, M, generator=1),
        TypeError,
        "generator: expected a torch.Generator or None, found int 1",
    ),
    (
        "glb None",
        lambda: __import__("torchmeshmetric.viz", fromlist=["glb_bytes"]).glb_bytes(None),
        TypeError,
        "mesh: expected an ErrorMesh",
    ),
    # F12: the mmetric-emulation helpers of torchmeshmetric.mpeg
    (
        "sq_dists shape",
        lambda: t.mpeg.mpeg_sq_dists(np.zeros((4, 2), np.float32), np.zeros((4, 2), np.float32)),
        ShapeError,
        r"query: expected shape \(\.\.\., 3\), found \(4, 2\)",
    ),
    (
        "sq_dists tensor",
        lambda: t.mpeg.mpeg_sq_dists(torch.zeros(4, 3), np.zeros((4, 3), np.float32)),
        TypeError,
        "query: expected a numpy array of",
    ),
    ("knn k 0", lambda: t.mpeg.k_nearest(_P32, _P32, 0), ValueError, "k: expected an int >= 1, found 0"),
    ("knn k 65", lambda: t.mpeg.k_nearest(_P32, _P32, 65), ValueError, r"k: expected an int in \[1, 64\], found 65"),
    ("knn k float", lambda: t.mpeg.k_nearest(_P32, _P32, 2.5), TypeError, "k: expected an int, found float 2.5"),
    ("knn empty", lambda: t.mpeg.k_nearest(_P32, _P32[:0], 1), ValueError, "target: expected at least one point"),
    (
        "lightness shape",
        lambda: t.mpeg.pcqm_lightness(torch.ones(5, 2)),
        ShapeError,
        r"colors: expected shape \(N, 3\), found \(5, 2\)",
    ),
    (
        "lightness negative",
        lambda: t.mpeg.pcqm_lightness(np.array([[-5.0, 0, 0]])),
        ValueError,
        r"colors: expected RGB values in \[0, 255\], found values in \[-5, 0\]",
    ),
    (
        "ycbcr 4 channels",
        lambda: t.mpeg.rgb_to_ycbcr(np.zeros((5, 4))),
        ShapeError,
        r"rgb: expected shape \(\.\.\., 3\), found \(5, 4\)",
    ),
    (
        "texture uv NaN",
        lambda: t.mpeg.sample_texture(_TEX, np.array([[np.nan, 0.5]], np.float32)),
        NonFiniteError,
        "uv: expected finite values, found 1 NaN/Inf",
    ),
    (
        "texture uv (N, 3)",
        lambda: t.mpeg.sample_texture(_TEX, np.zeros((5, 3), np.float32)),
        ShapeError,
        r"uv: expected shape \(N, 2\), found \(5, 3\)",
    ),
    (
        "texture empty",
        lambda: t.mpeg.sample_texture(np.zeros((0, 0, 3), np.uint8), np.zeros((1, 2), np.float32)),
        ShapeError,
        "texture: expected an",
    ),
    (
        "mean_psnr empty",
        lambda: t.mpeg.mean_psnr([]),
        ValueError,
        "values: expected at least one PSNR, found none",
    ),
    ("ctc clip", lambda: t.mpeg.ctc_mean([40.0], clip=-1), ValueError, "clip: expected a positive finite number"),
    (
        "flatten collision",
        lambda: __import__("torchmeshmetric.evaluation", fromlist=["x"]).flatten_statistics({"a/b": 1, "a": {"b": 2}}),
        ValueError,
        "nested: two statistics flatten to the key 'a/b'",
    ),
    # F11: truthy strings are no flags
    ("Mesh validate", lambda: t.Mesh(V, F, validate="no"), TypeError, "validate: expected a bool, found str 'no'"),
    ("vertex_set", lambda: t.vertex_set(M, referenced_only="yes"), TypeError, "referenced_only: expected a bool"),
    (
        "exact_quantiles",
        lambda: t.distance_statistics(D, exact_quantiles="no"),
        TypeError,
        "exact_quantiles: expected a bool, found str 'no'",
    ),
    ("accumulator", lambda: DistanceAccumulator(exact_quantiles="x"), TypeError, "exact_quantiles: expected a bool"),
    ("pair two_sided", lambda: _pair(two_sided="y"), TypeError, "two_sided: expected a bool, found str 'y'"),
    (
        "qem border",
        lambda: t.simplify_qem(M, 40, preserve_border="y"),
        TypeError,
        "preserve_border: expected a bool",
    ),
    ("MeshIndex flag", lambda: t.MeshIndex(M, referenced_only="no"), TypeError, "referenced_only: expected a bool"),
    ("save overwrite", lambda: t.save_mesh(M, "/nonexistent/x.ply", overwrite="no"), TypeError, "overwrite: expected"),
    # F11 / F10: peak shapes
    (
        "peak (2,) one set",
        lambda: t.distance_statistics(D, peak=torch.tensor([1.0, 2.0])),
        ShapeError,
        r"peak: expected a number or a tensor of shape \(\) \(one peak per item\), found shape \(2,\)",
    ),
    (
        "peak (3,) two sets",
        lambda: t.distance_statistics([D[:5], D[:3]], peak=torch.tensor([1.0, 2.0, 3.0])),
        ShapeError,
        r"peak: expected a number or a tensor of shape \(2,\)",
    ),
    # F5: the statistics helpers
    ("q negative", lambda: linear_quantiles(D, [-0.1]), ValueError, r"q: expected levels in \[0, 1\], found -0.1"),
    ("q above 1", lambda: linear_quantiles(D, [1.5]), ValueError, r"q: expected levels in \[0, 1\], found 1.5"),
    ("q NaN", lambda: linear_quantiles(D, [float("nan")]), ValueError, r"q: expected levels in \[0, 1\], found nan"),
    ("values 2-D", lambda: linear_quantiles(torch.rand(2, 5), [0.5]), ShapeError, r"values: expected shape \(N\)"),
    (
        "values NaN",
        lambda: linear_quantiles(torch.tensor([1.0, float("nan")]), [0.5]),
        ValueError,
        "values: expected finite values",
    ),
    ("mse negative", lambda: psnr_from_mse(torch.tensor(-1.0), 1.0), ValueError, "mse: expected mean squared"),
    ("mse str", lambda: psnr_from_mse("1", 1.0), TypeError, "mse: expected a tensor or a real number, found str"),
    ("peak 0", lambda: psnr_from_mse(torch.tensor(1.0), 0.0), ValueError, "peak: expected a finite number > 0"),
    ("peak NaN", lambda: psnr_from_mse(torch.tensor(1.0), float("nan")), ValueError, "peak: expected a finite"),
]


@pytest.mark.parametrize("call, error, message", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_refused_naming_the_argument(call: Callable[[], Any], error: type[Exception], message: str) -> None:
    with pytest.raises(error, match=message):
        call()


def test_numpy_and_tensor_integers_are_ints() -> None:
    # F14: these were refused as "expected an int ..., found np.int64(...)" (or failed in torch's iteration)
    g = torch.Generator().manual_seed(0)
    assert t.sample_surface(V, F, np.int64(5), generator=g).points.shape == (5, 3)
    assert t.sample_surface(V, F, torch.tensor(5)).points.shape == (5, 3)
    a = t.mesh_surface_distance_loss(V[:3], (V, F), surface_samples=np.int64(100))
    b = t.mesh_surface_distance_loss(V[:3], (V, F), surface_samples=100)
    assert torch.equal(a, b)
    assert t.demo_sequence(np.int64(2), resolution=np.int64(24)).num_frames == 2
    Vf = V.float()
    r = t.mpeg.mpeg_metrics((Vf, F), (Vf, F), grid_size=np.int64(16))
    assert r == t.mpeg.mpeg_metrics((Vf, F), (Vf, F), grid_size=16)


def test_psnr_from_mse_takes_a_number() -> None:
    assert psnr_from_mse(0.01, 1.0).item() == psnr_from_mse(torch.tensor(0.01, dtype=torch.float64), 1.0).item()
    assert psnr_from_mse(0.0, 1.0).item() == float("inf")


def test_one_peak_of_one_element_for_one_set() -> None:
    assert t.distance_statistics(D, peak=torch.tensor([2.0])).psnr.shape == ()


def test_mean_statistics_without_a_peak() -> None:
    # F9: psnr=None (no peak) raised TypeError: float() argument must be ... not 'NoneType'
    st = t.distance_statistics(D)
    out = mean_statistics([st, st])
    assert "psnr" not in out and out["ave"] == pytest.approx(float(st.ave))
    with pytest.raises(ValueError, match=re.escape("stats: psnr is None in pair 1 (computed without a peak?)")):
        mean_statistics([t.distance_statistics(D, peak=1.0), st])
