import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric import EmptyInputError, Mesh, as_mesh, nearest_vertex_distance, point_mesh_distance, sample_surface
from torchmeshmetric.data import add_capture_defects, demo_sequence
from torchmeshmetric.simplification import simplify_qem, simplify_registered_qem
from torchmeshmetric.simplification._target import resolve_target
from torchmeshmetric.simplification.registered_qem import _nearest_vertices


@pytest.fixture(scope="module")
def seq():
    return demo_sequence(5, resolution=48)


def _registered(seq, k):
    prev = seq.frames[k - 1]
    return Mesh(seq.transfer(prev.verts.double(), k - 1, k).float(), prev.faces)


def _check_manifold(out: Mesh, genus_of: Mesh) -> None:
    tm = out.to_trimesh()
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    assert tm.euler_number == genus_of.to_trimesh().euler_number
    assert torch.equal(out.faces.unique(), torch.arange(out.num_verts))  # no unreferenced vertex
    assert float(out.face_areas().min()) > 0


@pytest.mark.parametrize("target", [0.5, 0.25, 0.03, 1001, 2000])
def test_targets_met_and_manifold(seq, target):
    m = seq.frames[1]
    want = resolve_target(target, m.num_faces)
    for reg, w in ((None, 0.0), (_registered(seq, 1), 1.0)):
        out = simplify_registered_qem(m, reg, target, weight=w)
        assert want <= out.num_faces <= want + 1
        _check_manifold(out, m)


def test_sphere_no_flips():
    sphere = as_mesh(trimesh.creation.icosphere(subdivisions=4))
    out = simplify_registered_qem(sphere, None, 0.05, weight=0.0)
    assert abs(out.num_faces - 256) <= 1
    tri = out.verts[out.faces]
    n = torch.linalg.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], dim=-1)
    assert bool(((n * tri.mean(1)).sum(1) > 0).all())  # every normal still points outward
    assert float((out.verts.norm(dim=1) - 1).abs().max()) < 0.05


def test_weight_zero_equals_no_previous_frame(seq):
    m, reg = seq.frames[2], _registered(seq, 2)
    a = simplify_registered_qem(m, reg, 0.3, weight=0.0)
    b = simplify_registered_qem(m, None, 0.3)
    assert torch.equal(a.verts, b.verts) and torch.equal(a.faces, b.faces)


def _surface_error(out: Mesh, ref: Mesh, diag: float) -> tuple[float, float]:
    pts = sample_surface(out, n=1200, generator=torch.Generator().manual_seed(0)).points.double()
    ref64 = ref.to(dtype=torch.float64)
    return (
        float(point_mesh_distance(pts, ref64).dists.mean()) / diag,
        float(point_mesh_distance(out.verts.double(), ref64).dists.mean()) / diag,
    )


@pytest.mark.parametrize("target", [0.5, 0.1])
def test_weight_zero_comparable_to_fast_simplification(seq, target):
    """Plain QEM (weight 0) vs fast-simplification at the same face count, one-sided distance to the original.

    Measured (resolution-48 frames, mean distance / bbox diagonal, ours / fast-simplification): sampled surface
    0.71-0.98, vertices 0.96-1.31. Asserted: surface <= 1.25x, vertices <= 1.5x.
    """
    m = seq.frames[1]
    diag = float(m.bbox_diagonal())
    ours = simplify_registered_qem(m, None, target, weight=0.0)
    peer = simplify_qem(m, target)
    assert abs(ours.num_faces - peer.num_faces) <= 2
    s_ours, v_ours = _surface_error(ours, m, diag)
    s_peer, v_peer = _surface_error(peer, m, diag)
    assert s_ours <= 1.25 * s_peer
    assert v_ours <= 1.5 * v_peer


@pytest.mark.parametrize("k", [2, 4])
def test_registered_qem_closer_to_previous_frame(seq, k):
    """On the demo sequence (ground-truth-registered previous frame), weight 3, half the faces.

    Measured mean vertex distance to the registered frame k-1 / bbox diagonal: fast-simplification 1.38e-3 / 1.01e-3,
    ours weight 0 1.32e-3 / 1.03e-3, ours weight 3 1.02e-3 / 0.83e-3 (k = 2 / 4): 17-26 % closer. The distance to
    frame k grows (1.3-1.5x fast-simplification's), the trade-off the paper reports. Asserted: >= 10 % closer to
    k-1 than both plain QEMs, <= 1.8x fast-simplification's distance to k.
    """
    m, reg = seq.frames[k], _registered(seq, k)
    diag = float(m.bbox_diagonal())
    reg64, m64 = reg.to(dtype=torch.float64), m.to(dtype=torch.float64)
    peer = simplify_qem(m, 0.5)
    plain = simplify_registered_qem(m, reg, 0.5, weight=0.0)
    ours = simplify_registered_qem(m, reg, 0.5, weight=3.0)
    assert abs(ours.num_faces - peer.num_faces) <= 2

    def to_prev(x: Mesh) -> float:
        return float(point_mesh_distance(x.verts.double(), reg64).dists.mean()) / diag

    def to_cur(x: Mesh) -> float:
        return float(point_mesh_distance(x.verts.double(), m64).dists.mean()) / diag

    assert to_prev(ours) <= 0.9 * to_prev(peer)
    assert to_prev(ours) <= 0.9 * to_prev(plain)
    assert to_cur(ours) <= 1.8 * to_cur(peer)


def test_boundary_kept():
    grid = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=48)
    tm = trimesh.Trimesh(grid.vertices, grid.faces[grid.face_normals[:, 2] < 0.5])  # open tube, two boundary loops
    tube = as_mesh(trimesh.remesh.subdivide_to_size(tm.vertices, tm.faces, 0.08))
    tm_tube = tube.to_trimesh()
    edges = np.sort(tm_tube.edges, axis=1)
    uniq, cnt = np.unique(edges, axis=0, return_counts=True)
    boundary = np.unique(uniq[cnt == 1])
    out = simplify_registered_qem(tube, None, 0.3)
    assert abs(out.num_faces - resolve_target(0.3, tube.num_faces)) <= 1
    d = nearest_vertex_distance(tube.verts[boundary].double(), out.verts.double()).dists
    assert float(d.max()) == 0.0  # every boundary vertex kept in place


def test_defective_input(seq):
    noisy = add_capture_defects(seq.frames[1], seed=0)
    out = simplify_registered_qem(noisy, _registered(seq, 1), 0.5)
    want = resolve_target(0.5, noisy.num_faces)
    assert want <= out.num_faces <= want + 1
    assert torch.isfinite(out.verts).all()


def test_nearest_helper_matches_library_kernel(seq):
    pts = seq.frames[0].verts[:300].double()
    ref = seq.frames[1].verts.double()
    _, dist = _nearest_vertices(pts.numpy(), ref.numpy())
    res = nearest_vertex_distance(pts, ref)
    np.testing.assert_allclose(dist, res.dists.numpy(), rtol=0, atol=1e-12)


def test_bad_arguments(seq):
    m = seq.frames[0]
    with pytest.raises(ValueError, match="weight"):
        simplify_registered_qem(m, None, 0.5, weight=-1.0)
    with pytest.raises(ValueError, match="candidate_fraction"):
        simplify_registered_qem(m, None, 0.5, candidate_fraction=0.0)
    with pytest.raises(ValueError, match="max_distance"):
        simplify_registered_qem(m, None, 0.5, max_distance=0.0)
    with pytest.raises(ValueError, match="target"):
        simplify_registered_qem(m, None, 0)
    with pytest.raises(EmptyInputError, match="mesh_k"):
        simplify_registered_qem(Mesh(torch.zeros(3, 3), torch.zeros(0, 3, dtype=torch.long)), None, 0.5)


def test_mesh_arrays_weld_coincident_vertices(seq):
    from torchmeshmetric.simplification.registered_qem import mesh_arrays

    verts = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [-0.0, 0, 0], [0, 0, 1]])
    faces = torch.tensor([[0, 1, 2], [3, 2, 4], [4, 3, 5], [1, 3, 2]])
    # copies go to the first vertex at the same position (-0.0 is 0.0); [1, 3, 2] becomes [1, 1, 2]: dropped
    assert mesh_arrays(Mesh(verts, faces))[1].tolist() == [[0, 1, 2], [1, 2, 0], [0, 1, 5]]
    frame = seq.frames[1]  # no two vertices of a built-in frame coincide: its faces as they are
    assert np.array_equal(mesh_arrays(frame)[1], frame.faces.numpy())


def test_duplicate_vertices_do_not_stop_the_collapse(seq):
    # Captured frames store seams as duplicate vertices: unwelded, each seam was two open borders whose vertices the
    # collapse keeps fixed, and at 10 % both simplifiers stopped at 530-556 faces (2 % duplicates) and 1122-1148
    # (5 %) of 360, while QEM met it (found by review G). Welded, the target is met, and the error is the clean
    # frame's: measured 1.03-1.06x (Registered QEM) and 0.98-1.02x (Anchored QEM), duplicate seeds 0-2.
    from torchmeshmetric.simplification import simplify_anchored_qem

    m, reg = seq.frames[1], _registered(seq, 1)
    diag = float(m.bbox_diagonal())
    anchors = seq.transfer(simplify_qem(seq.frames[0], 0.1).verts.double(), 0, 1).float()
    clean = (simplify_registered_qem(m, reg, 0.1), simplify_anchored_qem(m, anchors, 0.1))
    clean_error = [_surface_error(out, m, diag)[0] for out in clean]
    for dup in (0.02, 0.05):
        # no zero-area faces (a, m, b) on an edge ab: their non-manifold edges lock vertices of their own (below)
        noisy = add_capture_defects(m, seed=0, duplicate_fraction=dup, normalize=False, num_collinear_faces=0)
        want = resolve_target(0.1, noisy.num_faces)
        outs = (simplify_registered_qem(noisy, reg, 0.1), simplify_anchored_qem(noisy, anchors, 0.1))
        for out, base in zip(outs, clean_error, strict=True):
            assert want <= out.num_faces <= want + 1
            assert _surface_error(out, m, diag)[0] <= 1.15 * base
    # With every defect, the 20 zero-area faces included, the target is met at 10 % as well.
    noisy = add_capture_defects(m, seed=0, duplicate_fraction=0.05, normalize=False)
    want = resolve_target(0.1, noisy.num_faces)
    assert want <= simplify_registered_qem(noisy, reg, 0.1).num_faces <= want + 1
    assert want <= simplify_anchored_qem(noisy, anchors, 0.1).num_faces <= want + 1


def test_a_missed_target_counts_the_fixed_vertices():
    # The warning said neither why nor which simplifier (Anchored QEM's named Registered QEM's). Here the 20 zero-area
    # faces of the defects: their non-manifold edges keep 58 vertices fixed at 3 % of a 1597-face frame.
    from torchmeshmetric.simplification import simplify_anchored_qem

    frame = demo_sequence(2, resolution=32).frames[1]
    noisy = add_capture_defects(frame, seed=1, duplicate_fraction=0.05, normalize=False)
    tail = r"no valid collapse left at 134 faces \(target 48\); 58 of its 79 vertices lie on a border or non-manifold"
    with pytest.warns(UserWarning, match="simplify_registered_qem: " + tail):
        simplify_registered_qem(noisy, None, 0.03)
    with pytest.warns(UserWarning, match="simplify_anchored_qem: " + tail):
        simplify_anchored_qem(noisy, torch.zeros(0, 3), 0.03)


def test_the_unit_of_the_coordinates_changes_nothing_but_rounding():
    # Unlike fast-simplification (an absolute stopping threshold, so simplify_qem works on a canonical copy), this
    # queue has only thresholds relative to the mesh (1e-9 * scale**3, 1e-12 * edge length): it needs no canonical
    # scale. Measured (review of the canonical extent, 2026-12-07): x1000, x0.0254 and x3.7 gave the same faces as x1
    # at 774, 387 and 155 of 1548 faces (Registered and Anchored QEM), vertices within 1.5e-14 units; x1024 the bits.
    from torchmeshmetric.simplification import simplify_anchored_qem

    a, b = (f.to(dtype=torch.float64) for f in demo_sequence(2, resolution=32).frames)
    for target in (774, 155):
        base = simplify_registered_qem(b, a, target)
        anchored = simplify_anchored_qem(b, base.verts[:50], target)
        for unit in (1000.0, 0.0254, 1024.0):
            reg = simplify_registered_qem(Mesh(b.verts * unit, b.faces), Mesh(a.verts * unit, a.faces), target)
            anc = simplify_anchored_qem(Mesh(b.verts * unit, b.faces), base.verts[:50] * unit, target)
            assert torch.equal(reg.faces, base.faces) and torch.equal(anc.faces, anchored.faces)
            bound = 0.0 if unit == 1024.0 else 1e-13  # measured 1.5e-14 at most
            assert float((reg.verts / unit - base.verts).abs().max()) <= bound
            assert float((anc.verts / unit - anchored.verts).abs().max()) <= bound
