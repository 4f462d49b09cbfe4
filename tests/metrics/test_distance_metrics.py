import math
import pickle

import numpy as np
import pytest
import torch
import trimesh
from torchmetrics import MetricCollection

from torchmeshmetric import EmptyInputError, Mesh, nearest_vertex_distance, point_mesh_distance, sample_surface
from torchmeshmetric._checks import NonFiniteError
from torchmeshmetric.metrics import (
    DistanceStatisticsMetric,
    MeshSurfaceDistance,
    NearestVertexDistance,
    mesh_surface_distance_sets,
    nearest_vertex_distance_sets,
)

KEYS = ["ave", "var", "std", "mse", "rmse", "max", "min", "median", "p95", "p99", "count", "psnr"]


def np_stats(d, peak):
    d = np.asarray(d, dtype=np.float64)
    return {
        "ave": d.mean(), "var": d.var(), "std": d.std(), "mse": np.mean(d**2), "rmse": np.sqrt(np.mean(d**2)),
        "max": d.max(), "min": d.min(), "median": np.percentile(d, 50), "p95": np.percentile(d, 95),
        "p99": np.percentile(d, 99), "count": d.size, "psnr": 10 * np.log10(peak**2 / np.mean(d**2)),
    }  # fmt: skip


def assert_close(out, ref, rtol=1e-10):
    for k, v in ref.items():
        assert float(out[k]) == pytest.approx(v, rel=rtol, abs=1e-300), k


def used_verts(m):
    v, f = m
    return v[np.unique(f.numpy())].numpy()


def oracle_surface(simp, ref):
    """Outside oracle: trimesh's closest-point query on the reference."""
    _, dist, _ = trimesh.proximity.closest_point(ref, used_verts(simp))
    return dist


def test_mesh_surface_distance_batch_by_batch_and_accumulated(frames):
    simps, refs = frames
    metric = MeshSurfaceDistance()
    batches = [([simps[0]], [refs[0]]), ([simps[1], simps[2]], [refs[1], refs[2]]), ([simps[3]], [refs[3]])]
    all_d, peak = [], 0.0
    for s, r in batches:
        d = np.concatenate([oracle_surface(a, b) for a, b in zip(s, r, strict=True)])
        batch_peak = max(float(np.linalg.norm(np.ptp(b.vertices, axis=0))) for b in r)
        out = metric(s, r)  # forward: this batch's statistics
        assert_close(out, np_stats(d, batch_peak), rtol=1e-6)  # trimesh's own rounding
        all_d.append(d)
        peak = max(peak, batch_peak)
    out = metric.compute()
    assert sorted(out) == sorted(KEYS)
    assert all(v.dim() == 0 and v.dtype == torch.float64 for v in out.values())
    assert_close(out, np_stats(np.concatenate(all_d), peak), rtol=1e-6)


def test_mesh_surface_distance_equals_kernel_exactly(frames):
    simps, refs = frames
    metric = MeshSurfaceDistance(peak=1.0)
    metric.update(simps, refs)
    d = torch.cat(
        [point_mesh_distance(torch.from_numpy(used_verts(s)), r).dists for s, r in zip(simps, refs, strict=True)]
    )
    assert_close(metric.compute(), np_stats(d.numpy(), 1.0), rtol=1e-12)


def test_nearest_vertex_distance_vs_scipy(frames):
    from scipy.spatial import cKDTree

    simps, refs = frames
    metric = NearestVertexDistance(peak=2.0)
    all_d = []
    for s, r in zip(simps, refs, strict=True):
        metric.update(s, r)
        all_d.append(cKDTree(r.vertices[np.unique(r.faces)]).query(used_verts(s))[0])
    assert_close(metric.compute(), np_stats(np.concatenate(all_d), 2.0), rtol=1e-10)


def test_two_sided_keys_and_values(frames):
    simps, refs = frames
    m = MeshSurfaceDistance(two_sided=True, peak=1.0)
    m.update(simps[:2], refs[:2])
    out = m.compute()
    r = mesh_surface_distance_sets(simps[:2], refs[:2], two_sided=True)
    assert_close({k: out["reverse_" + k] for k in KEYS}, np_stats(r.reverse.numpy(), 1.0), rtol=1e-12)
    assert float(out["symmetric_ave"]) == pytest.approx(0.5 * (r.forward.mean() + r.reverse.mean()).item(), rel=1e-12)
    assert float(out["hausdorff"]) == pytest.approx(max(r.forward.max(), r.reverse.max()).item(), rel=1e-12)
    sym_mse = max(float((r.forward.double() ** 2).mean()), float((r.reverse.double() ** 2).mean()))
    assert float(out["symmetric_mse"]) == pytest.approx(sym_mse, rel=1e-12)
    assert float(out["symmetric_rmse"]) == pytest.approx(math.sqrt(sym_mse), rel=1e-12)
    assert float(out["symmetric_psnr"]) == pytest.approx(-10 * math.log10(sym_mse), rel=1e-12)


def test_two_sided_catches_a_dropped_half():
    ref = trimesh.creation.icosphere(subdivisions=2)
    keep = ref.triangles_center[:, 2] > 0
    half = (torch.from_numpy(ref.vertices), torch.from_numpy(ref.faces[keep]))
    m = MeshSurfaceDistance(two_sided=True)
    m.update(half, ref)
    out = m.compute()
    assert float(out["max"]) == pytest.approx(0.0, abs=1e-12)  # one-sided: perfect score
    assert float(out["reverse_max"]) > 0.5 and float(out["hausdorff"]) > 0.5


def test_two_sided_surface_needs_a_mesh():
    with pytest.raises(TypeError, match="simplified"):
        MeshSurfaceDistance(two_sided=True).update(torch.zeros(3, 3), trimesh.creation.box())


def test_sampled_surface_mode_is_seeded_and_over_estimates(frames):
    simps, refs = frames
    m = MeshSurfaceDistance(surface_samples=500, seed=3, peak=1.0)
    m.update(simps[0], refs[0])
    gen = torch.Generator().manual_seed(3)
    samples = sample_surface(refs[0], n=500, generator=gen).points
    p = torch.from_numpy(used_verts(simps[0]))
    d = nearest_vertex_distance(p, samples).dists
    assert_close(m.compute(), np_stats(d.numpy(), 1.0), rtol=1e-12)
    exact = point_mesh_distance(p, refs[0]).dists
    assert bool((d >= exact - 1e-12).all())
    with pytest.raises(ValueError, match="surface_samples"):
        MeshSurfaceDistance(surface_samples=0)


def test_empty_update_is_a_noop_and_empty_compute_raises(frames):
    simps, refs = frames
    m = NearestVertexDistance()
    m.update(torch.zeros(0, 3), refs[0])
    with pytest.raises(EmptyInputError, match="no simplified"):
        m.compute()
    m.update(simps[0], refs[0])
    m.update(torch.zeros(0, 3), refs[0])
    ref = NearestVertexDistance()
    ref.update(simps[0], refs[0])
    assert_close(m.compute(), {k: float(v) for k, v in ref.compute().items()}, rtol=0)


def test_single_point_update():
    m = MeshSurfaceDistance(peak=10.0)
    m.update(torch.tensor([[0.0, 0.0, 3.0]], dtype=torch.float64), trimesh.creation.icosphere(subdivisions=3))
    out = m.compute()
    assert float(out["count"]) == 1 and float(out["var"]) == 0.0
    assert float(out["ave"]) == pytest.approx(2.0, rel=1e-12) and float(out["median"]) == float(out["ave"])


def test_float32_large_offset_inputs():
    rng = np.random.default_rng(0)
    offset = np.array([1e4, -2e4, 5e3])
    ref_pts = rng.uniform(0, 1, (200, 3)) + offset
    pts = ref_pts[:50] + rng.normal(0, 1e-3, (50, 3))
    m = NearestVertexDistance(peak=1.0)
    m.update(torch.from_numpy(pts).float(), torch.from_numpy(ref_pts).float())
    from scipy.spatial import cKDTree

    # float32 coordinates hold ~1e-3 absolute precision at 2e4: compare with the float32-rounded inputs.
    d = cKDTree(ref_pts.astype(np.float32).astype(np.float64)).query(pts.astype(np.float32).astype(np.float64))[0]
    assert_close(m.compute(), np_stats(d, 1.0), rtol=1e-4)


def test_approximate_quantiles_mode(frames):
    simps, refs = frames
    exact, approx = NearestVertexDistance(), NearestVertexDistance(exact_quantiles=False, relative_accuracy=0.01)
    for m in (exact, approx):
        m.update(simps, refs)
    e, a = exact.compute(), approx.compute()
    for k in ("ave", "var", "mse", "max", "min", "count", "psnr"):
        assert float(a[k]) == pytest.approx(float(e[k]), rel=1e-12)
    for k in ("median", "p95", "p99"):
        assert abs(float(a[k]) - float(e[k])) <= 0.01 * float(e[k]) * (1 + 1e-9)


@pytest.mark.filterwarnings(
    "ignore:The ``compute`` method of metric MeshSurfaceDistance was called before:UserWarning"
)  # after reset: on purpose
def test_metric_collection_state_dict_pickle_reset(frames):
    simps, refs = frames
    coll = MetricCollection({"surf": MeshSurfaceDistance(), "vert": NearestVertexDistance(two_sided=True)})
    coll.update(simps[:2], refs[:2])
    out = coll.compute()
    assert "surf_ave" in out and "vert_ave" in out and "vert_hausdorff" in out
    assert float(out["surf_ave"]) != float(out["vert_ave"])
    clone = pickle.loads(pickle.dumps(coll))
    assert {k: float(v) for k, v in clone.compute().items()} == {k: float(v) for k, v in out.items()}
    m = MeshSurfaceDistance()
    m.persistent(True)
    m.update(simps[0], refs[0])
    sd = m.state_dict()
    assert any(k.endswith("surface_moments") for k in sd)
    m2 = MeshSurfaceDistance()
    m2.persistent(True)
    m2.load_state_dict(sd)
    m2._update_count = 1
    assert float(m2.compute()["ave"]) == float(m.compute()["ave"])
    coll.reset()
    with pytest.raises(EmptyInputError):
        coll["surf"].compute()


def test_to_device_cpu_and_dtype_kept(frames):
    simps, refs = frames
    m = NearestVertexDistance().to("cpu")
    m.half()  # float64 states are not cast by torchmetrics' default dtype handling
    m.update(simps[0], refs[0])
    assert m.compute()["ave"].dtype == torch.float64


@pytest.mark.cuda
@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_cuda_matches_cpu(frames):
    simps, refs = frames
    cpu, gpu = MeshSurfaceDistance(two_sided=True), MeshSurfaceDistance(two_sided=True).to("cuda")
    cpu.update(simps, refs)
    gpu.update(
        [Mesh(*s).to("cuda") for s in simps],
        [Mesh(*(torch.from_numpy(np.asarray(x)) for x in (r.vertices, r.faces))).to("cuda") for r in refs],
    )
    for k, v in cpu.compute().items():
        assert float(gpu.compute()[k]) == pytest.approx(float(v), rel=1e-9), k


def test_distance_statistics_metric_without_peak_has_no_psnr():
    m = DistanceStatisticsMetric()
    m.update(torch.tensor([1.0, 2.0]))
    assert "psnr" not in m.compute()
    m.update(torch.tensor([3.0]), peak=4.0)
    assert float(m.compute()["psnr"]) == pytest.approx(10 * math.log10(16 / (14 / 3)), rel=1e-12)
    with pytest.raises(TypeError, match="reverse_dists"):
        DistanceStatisticsMetric(two_sided=True).update(torch.ones(2))


def test_batch_size_mismatch_and_bad_args(frames):
    simps, refs = frames
    with pytest.raises(ValueError, match="reference"):
        MeshSurfaceDistance().update(simps[:2], refs[:1])
    with pytest.raises(ValueError, match="reference"):
        nearest_vertex_distance_sets(simps[:2], refs[:3])
    with pytest.raises(ValueError, match="ddof"):
        NearestVertexDistance(ddof=-1)


def test_a_refused_update_changes_nothing():
    # A bad reverse set once left the forward distances counted and the reverse ones not (forward 2, reverse 1).
    m = DistanceStatisticsMetric(two_sided=True)
    m.update(torch.tensor([1.0]), torch.tensor([2.0]))
    with pytest.raises(NonFiniteError, match="reverse_dists"):
        m.update(torch.tensor([3.0]), torch.tensor([math.nan]))
    with pytest.raises(ValueError, match=r"peak: expected finite values > 0, found \[nan\]"):
        m.update(torch.tensor([3.0]), torch.tensor([4.0]), peak=math.nan)  # a NaN peak stuck for good
    out = m.compute()
    assert out["count"].item() == 1.0 and out["reverse_count"].item() == 1.0 and out["ave"].item() == 1.0


BAD_PEAKS = [(-3.0, ValueError), (0.0, ValueError), (math.inf, ValueError), ("3", TypeError), (True, TypeError)]


@pytest.mark.parametrize(("peak", "error"), [*BAD_PEAKS, (torch.tensor([]), TypeError)])
def test_peaks_are_checked(peak, error):
    m = DistanceStatisticsMetric()
    with pytest.raises(error, match="peak"):
        m.update(torch.tensor([1.0]), peak=peak)  # -3 was dropped in silence, "3" a raw torch error
    m.update(torch.tensor([1.0]), peak=torch.tensor([2.0, 4.0]))
    assert m.compute()["psnr"].item() == pytest.approx(10 * math.log10(16.0))


def test_the_sketch_refuses_negative_distances():
    # Log buckets: the median of [-5, -4, -3] came out -3. Exact quantiles take any sign.
    with pytest.raises(ValueError, match=r"dists: the quantile sketch takes distances >= 0, found -5.0"):
        DistanceStatisticsMetric(exact_quantiles=False).update(torch.tensor([-5.0, -4.0, -3.0]))
    exact = DistanceStatisticsMetric()
    exact.update(torch.tensor([-5.0, -4.0, -3.0]))
    assert exact.compute()["median"].item() == -4.0


@pytest.mark.parametrize("bad", ["batch", "reverse"])
def test_a_refused_forward_keeps_what_was_accumulated(bad):
    # forward() resets the states to compute the batch's value: an empty batch (or a NaN in reverse_dists) lost every
    # earlier update (found by review: compute() then raised "nothing accumulated").
    m = DistanceStatisticsMetric(two_sided=True)
    m(torch.tensor([1.0, 2.0]), torch.tensor([3.0]))
    m.update(torch.tensor([4.0]), torch.tensor([5.0]))
    with pytest.raises(EmptyInputError if bad == "batch" else NonFiniteError):
        if bad == "batch":
            m(torch.zeros(0), torch.zeros(0))
        else:
            m(torch.tensor([6.0]), torch.tensor([math.nan]))
    out = m.compute()
    assert out["count"].item() == 3.0 and out["ave"].item() == pytest.approx(7.0 / 3.0, rel=1e-15)
    assert out["reverse_count"].item() == 2.0 and m._update_count == 2
    assert m(torch.tensor([9.0]), torch.tensor([1.0]))["ave"].item() == 9.0  # forward still works after
    assert m.compute()["count"].item() == 4.0


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"two_sided": "no"}, TypeError, r"two_sided: expected a bool, found str 'no'"),  # was two-sided
        ({"exact_quantiles": 0}, TypeError, r"exact_quantiles: expected a bool, found int 0"),
        ({"ddof": True}, TypeError, r"ddof: expected an int, found bool True"),  # was ddof 1
        ({"peak": 0}, ValueError, r"peak: expected finite values > 0, found \[0\.0\]"),  # psnr was -inf
        ({"peak": math.inf}, ValueError, r"peak: expected finite values > 0"),
        ({"peak": "3"}, TypeError, r"peak: expected a number"),
        ({"peak": True}, TypeError, r"peak: expected a number"),
    ],
)
def test_constructor_arguments_are_checked_as_update_checks_them(kwargs, error, message):
    for cls in (DistanceStatisticsMetric, MeshSurfaceDistance, NearestVertexDistance):
        with pytest.raises(error, match=message):
            cls(**kwargs)


def test_loss_and_distance_options_are_checked():
    # detach_reference="False" detached the reference (no gradient reached it), two_sided="no" was two-sided,
    # surface_samples=True was 1 sample, seed=1.7 was seed 1 (found by review).
    from torchmeshmetric.metrics import MeshSurfaceDistanceLoss, NearestVertexDistanceLoss, mesh_surface_distance_sets

    for cls, key, value in [
        (MeshSurfaceDistanceLoss, "detach_reference", "False"),
        (MeshSurfaceDistanceLoss, "two_sided", "no"),
        (NearestVertexDistanceLoss, "two_sided", 1),
        (MeshSurfaceDistanceLoss, "seed", 1.7),
    ]:
        with pytest.raises(TypeError, match=rf"{key}: expected an? (bool|int), found"):
            cls(**{key: value})
    with pytest.raises(TypeError, match=r"surface_samples: expected an int, found bool True"):
        MeshSurfaceDistance(surface_samples=True)
    sphere = trimesh.creation.icosphere(subdivisions=1)
    with pytest.raises(TypeError, match=r"detach_reference: expected a bool, found str 'False'"):
        mesh_surface_distance_sets(torch.zeros(1, 3), sphere, detach_reference="False")
    with pytest.raises(TypeError, match=r"two_sided: expected a bool"):
        nearest_vertex_distance_sets(torch.zeros(1, 3), sphere, two_sided="yes")


def test_merge_state_refuses_other_states():
    # Sketches of two accuracies were added bin by bin: a raw "size of tensor a (27633) must match ... (2765)"
    # (found by review); DistanceAccumulator.merge already refused the same mistake in words.
    a = DistanceStatisticsMetric(exact_quantiles=False, relative_accuracy=0.01)
    a.update(torch.tensor([1.0, 2.0]))
    for other, shown in [
        (DistanceStatisticsMetric(exact_quantiles=False, relative_accuracy=0.001), "relative_accuracy=0.001"),
        (DistanceStatisticsMetric(), "exact_quantiles=True"),
        (DistanceStatisticsMetric(exact_quantiles=False, relative_accuracy=0.01, two_sided=True), "two_sided=True"),
    ]:
        with pytest.raises(ValueError, match=rf"incoming_state: DistanceStatisticsMetric\(.*{shown}.*\) cannot merge"):
            a.merge_state(other)
    with pytest.raises(ValueError, match=r"incoming_state: state 'forward_sketch' .* expected shape \(\d+,\), found"):
        a.merge_state({**a.metric_state, "forward_sketch": torch.zeros(3, dtype=torch.float64)})
    same = DistanceStatisticsMetric(exact_quantiles=False, relative_accuracy=0.01)
    same.update(torch.tensor([6.0]))
    a.merge_state(same)
    assert a.compute()["count"].item() == 3.0 and a.compute()["ave"].item() == 3.0


def test_meshes_without_faces_are_named():
    # "faces: mesh 0 has no faces" and "mesh: no vertex is referenced by a face" named neither argument (review).
    sphere = trimesh.creation.icosphere(subdivisions=1)
    bare = Mesh(torch.rand(5, 3), torch.zeros(0, 3, dtype=torch.long), validate=False)
    with pytest.raises(EmptyInputError, match=r"^reference: expected a surface to measure to, found 5 vertices and no"):
        MeshSurfaceDistance().update(torch.rand(5, 3), bare)
    with pytest.raises(EmptyInputError, match=r"^reference\[1\]: expected a surface"):
        MeshSurfaceDistance().update([torch.rand(5, 3), torch.rand(2, 3)], [sphere, bare])
    with pytest.raises(EmptyInputError, match=r"^reference: no vertex is referenced by a face \(5 vertices, 0 faces\)"):
        NearestVertexDistance().update(torch.rand(5, 3), bare)
    with pytest.raises(EmptyInputError, match=r"^simplified: no vertex is referenced by a face"):
        MeshSurfaceDistance(two_sided=True).update(bare, sphere)
    m = DistanceStatisticsMetric()
    m.update(torch.tensor([3, 4], dtype=torch.int16))  # every integer dtype is exact (int16 was refused, int32 taken)
    assert m.compute()["ave"].item() == 3.5
    with pytest.raises(TypeError, match=r"dists: expected a float or integer tensor, found dtype torch.bool"):
        m.update(torch.tensor([True]))


def test_old_checkpoints_of_several_moments_rows_still_merge():
    # Checkpoints written before the moments became one row hold one row per forward() call: loaded, they then
    # failed a merge_state or a sync with "stack expects each tensor to be equal size" (found by review).
    from torchmeshmetric.stats.moments import moments_of, moments_rows

    parts = [torch.tensor([1.0, 2.0]), torch.tensor([6.0])]
    rows = torch.cat([moments_rows(moments_of(p)) for p in parts])
    old = DistanceStatisticsMetric()
    old.persistent(True)
    state = old.state_dict()
    state["forward_moments"] = rows
    state["forward_values"] = [p.double() for p in parts]
    m = DistanceStatisticsMetric()
    m.persistent(True)
    m.load_state_dict(state)
    m._update_count = 1  # a loaded state counts no update (as in test_metric_collection_and_state_dict)
    assert m.forward_moments.shape == (1, 6)
    other = DistanceStatisticsMetric()
    other.update(torch.tensor([3.0]))
    m.merge_state(other)
    assert m.compute()["count"].item() == 4.0 and m.compute()["ave"].item() == 3.0
    fresh = DistanceStatisticsMetric()
    fresh.update(torch.tensor([3.0]))
    fresh.merge_state(
        {
            "forward_moments": rows,
            "forward_values": [torch.tensor([1.0, 2.0, 6.0], dtype=torch.float64)],
            "reference_peak": torch.tensor(float("-inf"), dtype=torch.float64),
        }
    )
    assert fresh.compute()["count"].item() == 4.0 and fresh.compute()["ave"].item() == 3.0


def test_numpy_and_torch_scalars_are_taken_for_flags_counts_and_peaks():
    # The checks of 2026-12-07 refused np.float32 peaks, np.bool_ flags and one-element integer tensors that worked
    # before (found by review); str and float stay refused.
    from torchmeshmetric.metrics import MeshSurfaceDistanceLoss

    m = DistanceStatisticsMetric(peak=np.float32(10), two_sided=np.True_, exact_quantiles=np.bool_(True))
    assert m.fixed_peak == 10.0 and m.two_sided is True
    assert DistanceStatisticsMetric(peak=np.int64(4), ddof=np.int64(1)).ddof == 1
    MeshSurfaceDistanceLoss(detach_reference=np.False_, seed=np.int32(3), two_sided=torch.tensor(True))
    assert MeshSurfaceDistance(seed=torch.tensor(5)).seed == 5
    with pytest.raises(TypeError, match=r"seed: expected an int, found float 1.5"):
        MeshSurfaceDistance(seed=1.5)


def test_sampled_mode_does_not_depend_on_the_batch():
    # Review Q: one generator drew the samples of a whole batch, so a mesh measured alone and second in a batch got
    # other samples (distances up to 0.19 apart), and update([a, c], [d, b]) != update(a, d); update(c, b).
    a, b = trimesh.creation.icosphere(subdivisions=1), trimesh.creation.icosphere(subdivisions=3)
    c, d = trimesh.creation.capsule(), trimesh.creation.box()
    for two_sided in (False, True):
        batched = MeshSurfaceDistance(surface_samples=200, seed=7, two_sided=two_sided)
        one_by_one = MeshSurfaceDistance(surface_samples=200, seed=7, two_sided=two_sided)
        reversed_order = MeshSurfaceDistance(surface_samples=200, seed=7, two_sided=two_sided)
        batched.update([a, c], [d, b])
        one_by_one.update(a, d)
        one_by_one.update(c, b)
        reversed_order.update([c, a], [b, d])
        ref = batched.compute()
        for other in (one_by_one.compute(), reversed_order.compute()):
            for key in ref:
                assert float(other[key]) == pytest.approx(float(ref[key]), rel=1e-14, abs=1e-15), key


def test_sampled_loss_of_a_batch_is_the_sum_of_its_pairs():
    from torchmeshmetric.metrics import mesh_surface_distance_loss

    a, b = trimesh.creation.icosphere(subdivisions=1), trimesh.creation.icosphere(subdivisions=3)
    c, d = trimesh.creation.capsule(), trimesh.creation.box()
    for two_sided in (False, True):
        kw = {"surface_samples": 150, "seed": 2, "two_sided": two_sided, "reduction": "sum"}
        batch = mesh_surface_distance_loss([a, c], [d, b], **kw)
        pairs = mesh_surface_distance_loss(a, d, **kw) + mesh_surface_distance_loss(c, b, **kw)
        swapped = mesh_surface_distance_loss([c, a], [b, d], **kw)
        assert float(batch) == pytest.approx(float(pairs), rel=1e-14)
        assert float(swapped) == pytest.approx(float(pairs), rel=1e-14)
