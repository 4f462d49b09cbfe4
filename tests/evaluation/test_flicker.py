"""The flicker set, the registration's warp of arbitrary points, and registrations cached with their warp."""

import json

import pytest
import torch

from tests.evaluation.eval_helpers import TranslationRegister, sphere
from tests.registration.expected_warnings import expects_not_converged
from torchmeshmetric import Mesh
from torchmeshmetric.evaluation import (
    TemporalConsistency,
    evaluate_pair,
    evaluate_sequence,
    flicker_distances,
    registration_settings,
    report_dict,
)
from torchmeshmetric.registration import (
    DEFAULT_SCHEDULE,
    CachedRegistration,
    RegistrationCache,
    RegistrationWarp,
    SurfaceWarp,
    register_nonrigid,
    registration_key,
)

SHORT = (DEFAULT_SCHEDULE[0]._replace(max_steps=10),)  # a real graph fit, cheap: the tests check the warp, not the fit


def _fast():
    """Options of a cheap, reproducible registration (a fresh generator each call: tests run in any order)."""
    return {
        "schedule": SHORT,
        "num_points": 300,
        "num_target_samples": 300,
        "generator": torch.Generator().manual_seed(0),
    }


def _scaled(mesh: Mesh, factor: float, shift: float = 0.0) -> Mesh:
    return Mesh(mesh.verts * factor + torch.tensor([shift, 0.0, 0.0], dtype=mesh.dtype), mesh.faces)


def test_stable_simplification_has_no_flicker_and_alternating_scale_has_exactly_twice_the_offset():
    coarse = sphere(1)
    eps = 1e-3
    shift = torch.tensor([0.1, 0.0, 0.0], dtype=coarse.dtype)
    same = flicker_distances(_scaled(coarse, 1.0, 0.1), coarse, lambda p: p + shift)
    assert float(same.dists.max()) < 1e-12 and float(same.reverse.max()) < 1e-12
    # frame k-1 shrunk by eps, frame k grown by eps: every vertex of k is 2 eps (radially) from the vertex of k-1
    # below it, which is its closest point (the radial direction is in the normal cone of an icosphere vertex)
    r = flicker_distances(_scaled(coarse, 1 + eps), _scaled(coarse, 1 - eps), lambda p: p)
    assert torch.allclose(r.dists, torch.full_like(r.dists, 2 * eps), rtol=0, atol=1e-12)
    assert bool((r.reverse > 0).all()) and bool((r.reverse <= 2 * eps + 1e-12).all())
    # the piecewise-linear map of registered vertices: a face centroid (and a point above it) moves by the mean
    # displacement of the face's corners
    centroids = coarse.verts[coarse.faces].mean(1)
    tri = coarse.verts[coarse.faces]
    normals = torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1)
    above = centroids + 0.01 * normals / normals.norm(dim=-1, keepdim=True)
    doubled = SurfaceWarp(coarse, coarse.verts * 2)
    assert torch.allclose(doubled(centroids), 2 * centroids, rtol=0, atol=1e-12)
    assert torch.allclose(doubled(above), above + centroids, rtol=0, atol=1e-12)
    one_sided = flicker_distances(coarse, coarse, lambda p: p, two_sided=False)
    assert one_sided.reverse is None


@expects_not_converged
def test_flicker_of_the_original_frame_k_minus_1_is_the_papers_k_minus_1_surface_set():
    """With the original k-1 as 'simplified k-1', moving it by the warp gives the registered mesh: flicker ==
    surface_k_minus_1, for a registration given as a mesh (SurfaceWarp) and as a NonRigidRegistration (graph)."""
    src, dst, simp = sphere(2), sphere(3, offset=(0.02, 0, 0)), sphere(1, offset=(0.02, 0, 0))
    dst = Mesh(dst.verts * torch.tensor([1.05, 1.0, 0.95], dtype=dst.dtype), dst.faces)
    reg = register_nonrigid(src, dst, **_fast())
    for given in (reg, reg.mesh):
        r = evaluate_pair(simp, dst, src, precomputed_registration=given, simplified_k_minus_1=src)
        assert torch.allclose(r.distances["flicker"], r.distances["surface_k_minus_1"], rtol=0, atol=1e-12)
        assert torch.allclose(
            r.reverse_distances["flicker"], r.reverse_distances["surface_k_minus_1"], rtol=0, atol=1e-12
        )


@expects_not_converged
def test_graph_warp_reproduces_the_registration_and_composes_rigid_normalisation_and_graph():
    src, dst = sphere(3), sphere(3)
    dst = Mesh(dst.verts * torch.tensor([1.1, 1.0, 0.9], dtype=dst.dtype), dst.faces)
    reg = register_nonrigid(src, dst, **_fast())
    warp = RegistrationWarp.from_registration(reg, dst)
    assert torch.allclose(warp(src.verts), reg.verts, rtol=0, atol=1e-12)
    # known answer off the vertices: rigid motion, then every node translated by tau (identity node rotations)
    # moves any point by R p + t + tau * diagonal
    angle = torch.tensor(0.3, dtype=torch.float64)
    c, s_ = torch.cos(angle), torch.sin(angle)
    rot = torch.stack([torch.stack([c, -s_, c * 0]), torch.stack([s_, c, c * 0]), torch.tensor([0.0, 0, 1]).double()])
    rigid = torch.eye(4, dtype=torch.float64)
    rigid[:3, :3], rigid[:3, 3] = rot, torch.tensor([0.3, -0.2, 0.1]).double()
    tau = torch.tensor([0.01, 0.02, -0.03], dtype=torch.float64)
    known = warp._replace(
        rigid=rigid, rotations=torch.eye(3).double().expand_as(warp.rotations), translations=tau.expand_as(warp.nodes)
    )
    points = torch.randn(50, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(1))
    expected = points @ rot.T + rigid[:3, 3] + tau * warp.diagonal
    assert torch.allclose(known(points), expected, rtol=0, atol=1e-12)
    assert known(points.float()).dtype == torch.float32
    with pytest.raises(ValueError, match="points"):
        warp(torch.zeros(4, 2, dtype=torch.float64))


def test_sequence_has_flicker_from_frame_1_in_aggregate_and_json(moving_spheres):
    original, simplified = moving_spheres
    # frame k's simplification alternates between the coarse sphere scaled up and down by 1e-3
    flick = [_scaled(sphere(1), 1 + (1e-3 if k % 2 else -1e-3), 0.1 * k) for k in range(4)]
    seq = evaluate_sequence(original, flick, registration_fn=TranslationRegister())
    assert [p.frame for p in seq.pairs] == [1, 2, 3] and all("flicker" in p.statistics for p in seq.pairs)
    assert seq.set_names[-1] == "flicker" and "flicker" in seq.aggregate() and "flicker" in seq.aggregate_reverse()
    aves = [p.statistics["flicker"].ave for p in seq.pairs]
    # k odd: k grown, k-1 shrunk -> exactly 2 eps; k even: k's vertices inside k-1's polytope -> at most 2 eps
    assert aves[0] == pytest.approx(2e-3, abs=1e-12) and aves[2] == pytest.approx(2e-3, abs=1e-12)
    assert 1e-3 < aves[1] <= 2e-3 + 1e-12
    stable = evaluate_sequence(original, simplified, registration_fn=TranslationRegister())
    assert stable.aggregate()["flicker"]["max"] < 1e-12
    data = json.loads(json.dumps(report_dict({"a": seq})))
    body = data["methods"]["a"]
    assert body["pairs"][0]["flicker"]["ave"] == seq.pairs[0].statistics["flicker"].ave
    assert body["aggregate"]["flicker"]["ave"] == seq.aggregate()["flicker"]["ave"]
    assert "flicker" in body["aggregate"]["reverse"]
    # evaluate_pair without the simplified k-1 has no flicker set (as frame 0 has none)
    alone = evaluate_pair(simplified[1], original[1], original[0], precomputed_registration=original[0])
    assert "flicker" not in alone.statistics and alone.set_names[-1] == "vertex_k"


def test_registration_error_to_the_true_motion():
    a, b = sphere(1), sphere(1, offset=(0.1, 0, 0))
    truth = a.verts + torch.tensor([0.1, 0.0, 0.0], dtype=a.dtype)
    exact = evaluate_pair(a, b, a, registration_fn=TranslationRegister(), true_registration=truth)
    assert exact.registration_error_statistics.max == pytest.approx(0.0, abs=1e-12)
    off = evaluate_pair(a, b, a, registration_fn=TranslationRegister(0.13), true_registration=truth)
    assert off.registration_error_statistics.ave == pytest.approx(0.03, rel=1e-9)
    assert off.as_dict()["registration"]["error"]["max"] == pytest.approx(0.03, rel=1e-9)
    x = torch.tensor([1.0, 0.0, 0.0], dtype=a.dtype)
    seq = evaluate_sequence(
        [a, b], [a, b], registration_fn=TranslationRegister(0.13), ground_truth=lambda p, s, d: p + 0.1 * (d - s) * x
    )
    assert seq.aggregate_registration()["error"]["ave"] == pytest.approx(0.03, rel=1e-9)


def test_default_registration_is_cached_with_its_warp_and_old_entries_are_recomputed(tmp_path, monkeypatch):
    src, dst = sphere(2), sphere(2, offset=(0.02, 0, 0))
    options = {"schedule": SHORT, "num_points": 300, "num_target_samples": 300}  # the default generator: seed 0
    cache = RegistrationCache(tmp_path)
    r1 = evaluate_pair(src, dst, src, registration_cache=cache, registration_options=options, simplified_k_minus_1=src)
    assert isinstance(cache._memory[registration_key(src, dst, registration_settings(None, options))].warp,
                      RegistrationWarp)  # fmt: skip
    fresh = RegistrationCache(tmp_path)  # a new run reads the disk entry, warp included
    r2 = evaluate_pair(src, dst, src, registration_cache=fresh, registration_options=options, simplified_k_minus_1=src)
    assert fresh.hits == 1 and torch.equal(r1.distances["flicker"], r2.distances["flicker"])
    # an entry without its warp is recomputed and replaced, not half-used (the entries of the format before the warp
    # have other keys; one edited so is damaged: it no longer matches its checksum, review I #3)
    (path,) = tmp_path.glob("*.pt")
    old = torch.load(path, weights_only=True)
    del old["warp"]
    torch.save(old, path)
    again = RegistrationCache(tmp_path)
    with pytest.warns(UserWarning, match=r"is damaged: its content does not match its checksum \(sha256\)"):
        evaluate_pair(src, dst, src, registration_cache=again, registration_options=options, simplified_k_minus_1=src)
    assert again.misses == 1 and "warp" in torch.load(path, weights_only=True)
    # a caller's callable warp is used directly but never cached (it cannot be stored)
    given = CachedRegistration(src.verts, torch.zeros(src.num_verts), True, 0.0, lambda p: p)
    mem = RegistrationCache()
    entry, _ = mem.get_or_compute(src, dst, {}, lambda: given)
    assert entry.warp is None


def test_temporal_consistency_flicker_api(moving_spheres):
    original, simplified = moving_spheres
    metric = TemporalConsistency(flicker=True, registration_fn=TranslationRegister())
    with pytest.raises(ValueError, match="simplified_k_minus_1: required"):
        metric.update(simplified[1], original[1], original[0])
    for k in (1, 2, 3):
        metric.update(simplified[k], original[k], original[k - 1], simplified[k - 1])
    out = metric.compute()
    assert float(out["flicker"]["max"]) < 1e-12 and "flicker" in out["reverse"]
    plain = TemporalConsistency(registration_fn=TranslationRegister())
    with pytest.raises(ValueError, match="flicker=True"):
        plain.update(simplified[1], original[1], original[0], simplified[0])
    with pytest.raises(TypeError, match="flicker"):
        TemporalConsistency(flicker="yes")


@pytest.mark.parametrize(
    ("warp", "error", "match"),
    [
        (
            lambda p: torch.cat([p, p]),
            "ShapeError",
            r"warp\(simplified_k_minus_1.verts\): expected shape \(42, 3\), found \(84, 3\)",
        ),
        (lambda p: p[:-3], "ShapeError", r"expected shape \(42, 3\), found \(39, 3\)"),
        (lambda p: p[:, :2], "ShapeError", r"expected shape \(42, 3\), found \(42, 2\)"),
        (
            lambda p: p.numpy(),
            "TypeError",
            r"warp\(simplified_k_minus_1.verts\): expected a \(V, 3\) torch.Tensor, found numpy",
        ),
        (lambda p: p.long(), "DTypeError", r"warp\(simplified_k_minus_1.verts\): expected a floating-point tensor"),
        (lambda p: p + float("nan"), "NonFiniteError", r"warp\(simplified_k_minus_1.verts\): expected finite values"),
        (lambda p: p * float("inf"), "NonFiniteError", r"warp\(simplified_k_minus_1.verts\): expected finite values"),
    ],
)
def test_flicker_checks_the_warps_output(warp, error: str, match: str) -> None:
    """A registration's wrong output crashed deep in the kernel, or gave a plausible number (review K)."""
    import torchmeshmetric._checks as checks

    mesh = sphere(1)
    assert mesh.verts.shape[0] == 42
    exc = TypeError if error == "TypeError" else getattr(checks, error)
    with pytest.raises(exc, match=match):
        flicker_distances(mesh, mesh, warp)
