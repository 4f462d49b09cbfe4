import math

import numpy as np
import pytest
import torch
import trimesh
from scipy.spatial import cKDTree

from tests.evaluation.eval_helpers import TranslationRegister, sphere
from torchmeshmetric import IndexCache, Mesh, ShapeError
from torchmeshmetric.evaluation import SET_NAMES, evaluate_pair, evaluate_sequence, mean_statistics
from torchmeshmetric.metrics import mesh_surface_distance_sets, nearest_vertex_distance_sets
from torchmeshmetric.stats import distance_statistics


def _oracle_surface(points: torch.Tensor, mesh: Mesh) -> np.ndarray:
    tm = trimesh.Trimesh(mesh.verts.numpy(), mesh.faces.numpy(), process=False)
    return trimesh.proximity.closest_point(tm, points.numpy())[1]


def _oracle_vertex(points: torch.Tensor, ref: torch.Tensor) -> np.ndarray:
    return cKDTree(ref.numpy()).query(points.numpy())[0]


def test_four_sets_use_the_right_references():
    # simplified == original_k exactly -> both "k" sets are 0; the registered k-1 is a larger sphere (radius 1.1),
    # so both "k-1" sets are the distances to *that* mesh (checked against trimesh / scipy), not to original k-1.
    original_k = sphere(2)
    original_km1 = sphere(2, offset=(5.0, 0, 0))  # far away: using it unregistered would give distances ~4-6
    registered = sphere(2, radius=1.1)
    r = evaluate_pair(original_k, original_k, original_km1, precomputed_registration=registered)
    assert r.distances["surface_k"].abs().max() < 1e-12
    assert r.distances["vertex_k"].abs().max() < 1e-12
    pts = original_k.verts
    np.testing.assert_allclose(r.distances["surface_k_minus_1"].numpy(), _oracle_surface(pts, registered), atol=1e-12)
    np.testing.assert_allclose(
        r.distances["vertex_k_minus_1"].numpy(), _oracle_vertex(pts, registered.verts), atol=1e-12
    )
    # vertices of a unit icosphere to the same icosphere scaled by 1.1: exactly 0.1 to the nearest vertex
    np.testing.assert_allclose(r.distances["vertex_k_minus_1"].numpy(), 0.1, atol=1e-12)
    assert 0.05 < float(r.distances["surface_k_minus_1"].min()) <= 0.1 + 1e-12
    # the statistics are those of the kept sets
    for name in SET_NAMES:
        assert r.statistics[name] == distance_statistics(r.distances[name], peak=r.peak)
    # reverse sets: reference vertices -> simplified
    np.testing.assert_allclose(
        r.reverse_distances["surface_k_minus_1"].numpy(), _oracle_surface(registered.verts, original_k), atol=1e-12
    )
    np.testing.assert_allclose(r.reverse_distances["vertex_k"].numpy(), 0.0, atol=1e-12)


def test_register_called_with_k_minus_1_onto_k_and_residual_is_to_frame_k():
    seen = []

    def register(source, target):
        seen.append((source.verts.clone(), target.verts.clone()))
        return Mesh(source.verts + torch.tensor([0.1, 0.0, 0.0], dtype=torch.float64), source.faces)

    km1, k = sphere(2), sphere(2, offset=(0.1, 0, 0))
    r = evaluate_pair(sphere(1, offset=(0.1, 0, 0)), k, km1, registration_fn=register)
    assert len(seen) == 1
    assert torch.equal(seen[0][0], km1.verts) and torch.equal(seen[0][1], k.verts)
    assert r.registration_residual.abs().max() < 1e-12  # perfect registration
    assert r.motion == pytest.approx(0.1 / float(k.bbox_diagonal()), rel=1e-12)
    # perfect registration: the k-1 and k sets coincide
    torch.testing.assert_close(r.distances["surface_k"], r.distances["surface_k_minus_1"], atol=1e-12, rtol=0)


def test_dropping_half_of_the_mesh_is_caught_by_the_two_sided_report():
    full = sphere(2)
    centroids = full.verts[full.faces].mean(1)
    half = Mesh(full.verts, full.faces[centroids[:, 2] > 0])
    good = evaluate_pair(full, full, full, precomputed_registration=full)
    bad = evaluate_pair(half, full, full, precomputed_registration=full)
    # one-sided (the paper's sets): the half mesh looks perfect
    assert bad.statistics["surface_k"].max < 1e-12 and bad.statistics["vertex_k"].max < 1e-12
    # two-sided: the missing half is up to ~a radius away from the remaining surface
    assert good.reverse_statistics["surface_k"].max < 1e-12
    assert bad.reverse_statistics["surface_k"].max > 0.9
    assert bad.reverse_statistics["vertex_k"].rmse > 0.3


def test_one_sided_has_no_reverse_sets():
    r = evaluate_pair(sphere(1), sphere(2), sphere(2), precomputed_registration=sphere(2), two_sided=False)
    assert r.reverse_distances == {} and r.reverse_statistics == {}
    assert set(r.distances) == set(SET_NAMES)


def test_registration_of_wrong_shape_is_rejected():
    with pytest.raises(ShapeError, match="registration"):
        evaluate_pair(sphere(1), sphere(2), sphere(2), precomputed_registration=sphere(1))


def test_sequence_aggregate_is_mean_of_pairs_and_best_pair_is_least_motion(moving_spheres):
    original, simplified = moving_spheres
    # make pair (1, 2) move less: registration shifts differ per pair
    shifts = {1: 0.1, 2: 0.02, 3: 0.1}
    regs = [
        Mesh(original[k - 1].verts + torch.tensor([shifts[k], 0, 0], dtype=torch.float64), original[k - 1].faces)
        for k in range(1, 4)
    ]
    seq = evaluate_sequence(original, simplified, precomputed_registrations=regs)
    assert [p.frame for p in seq.pairs] == [1, 2, 3]
    agg = seq.aggregate()
    for name in SET_NAMES:
        for field in ("ave", "var", "std", "mse", "rmse", "psnr"):
            expect = sum(float(getattr(p.statistics[name], field)) for p in seq.pairs) / 3
            assert agg[name][field] == pytest.approx(expect, rel=1e-12)
    assert seq.best_pair_index() == 1 and seq.pairs[1].frame == 2
    assert mean_statistics([p.statistics["surface_k"] for p in seq.pairs]) == agg["surface_k"]


def test_frame_count_mismatch(moving_spheres):
    original, simplified = moving_spheres
    with pytest.raises(ValueError, match="simplified_frames"):
        evaluate_sequence(original, simplified[:-1], registration_fn=TranslationRegister())


def test_progress_reports_every_pair(moving_spheres):
    original, simplified = moving_spheres
    calls = []
    evaluate_sequence(
        original, simplified, registration_fn=TranslationRegister(), progress=lambda k, n: calls.append((k, n))
    )
    assert calls == [(1, 3), (2, 3), (3, 3)]


def test_sets_are_the_metrics_sets_and_each_reference_index_is_built_once(moving_spheres):
    original, simplified = moving_spheres
    register = TranslationRegister()
    indexes = IndexCache(max_entries=64)
    first = evaluate_sequence(original, simplified, registration_fn=register, indexes=indexes)
    built = len(indexes)
    assert 0 < built <= 2 * (len(original) - 1)  # frame k and registered frame k-1 of each pair, at most
    assert all(index.tree == "morton" for index in indexes._entries.values())  # cheap builds: few queries each
    other = [sphere(1, radius=0.98, offset=(0.1 * k, 0, 0)) for k in range(len(original))]  # a second method
    evaluate_sequence(original, other, registration_fn=register, indexes=indexes)
    assert len(indexes) == built  # the references' indexes were found again, none rebuilt
    # The pipeline's sets are those of the metrics' functions (computed here without any index), bit for bit.
    for k, pair in enumerate(first.pairs, start=1):
        registered = Mesh(
            original[k - 1].verts + torch.tensor([0.1, 0.0, 0.0], dtype=torch.float64), original[k - 1].faces
        )
        for name, reference in (("k", original[k]), ("k_minus_1", registered)):
            for kind, distance_sets in (
                ("surface", mesh_surface_distance_sets),
                ("vertex", nearest_vertex_distance_sets),
            ):
                sets = distance_sets(simplified[k], reference, two_sided=True)
                assert torch.equal(pair.distances[f"{kind}_{name}"], sets.forward)
                assert torch.equal(pair.reverse_distances[f"{kind}_{name}"], sets.reverse)


def test_mean_psnr_over_pairs_leaves_a_lossless_pair_out_never_inf():
    # One pair measured without error (psnr inf) made the method's Table III/IV mean PSNR inf whatever the other
    # pairs lost (found by review E); the library's rule (mean_psnr, the MPEG averages'): the mean over finite pairs.
    lossless = distance_statistics(torch.zeros(4, dtype=torch.float64), peak=2.0)
    lossy = distance_statistics(torch.tensor([0.0, 0.02, 0.02, 0.0], dtype=torch.float64), peak=2.0)
    assert lossless.psnr == math.inf
    mean = mean_statistics([lossless, lossy, lossy])
    assert mean["psnr"] == pytest.approx(10 * math.log10(4.0 / 2e-4), abs=1e-12)  # 43.01 dB: the lossy pairs'
    assert mean["mse"] == pytest.approx(2 * 2e-4 / 3, rel=1e-12)  # every other field over every pair, as before
    assert mean_statistics([lossless, lossless])["psnr"] == math.inf  # inf only when every pair is
