import warnings

import pytest
import torch
import trimesh

from torchmeshmetric import EmptyInputError, Mesh, as_mesh
from torchmeshmetric.simplification import simplify_qem
from torchmeshmetric.simplification._target import resolve_target


@pytest.fixture(scope="module")
def sphere() -> Mesh:
    return as_mesh(trimesh.creation.icosphere(subdivisions=4))  # 5120 faces


@pytest.mark.parametrize("target", [2560, 1000, 0.5, 0.03, 0.2])
def test_targets_met(sphere, target):
    out = simplify_qem(sphere, target)
    want = resolve_target(target, sphere.num_faces)
    assert abs(out.num_faces - want) <= 2
    tm = out.to_trimesh()
    assert tm.is_watertight and tm.volume > 0
    # still a unit sphere
    r = out.verts.norm(dim=1)
    assert float((r - 1).abs().max()) < 0.05


def test_identity_and_dtype(sphere):
    # At 1.0 the input itself came back, still requiring grad, though documented as detached (review G): now a
    # detached copy, as at every other target (this test asserted `is sphere`, the behaviour being fixed).
    verts = sphere.verts.clone().requires_grad_(True)
    same = simplify_qem(Mesh(verts, sphere.faces), 1.0)
    assert torch.equal(same.verts, sphere.verts) and torch.equal(same.faces, sphere.faces)
    assert not same.verts.requires_grad and same.verts.grad_fn is None
    assert same.verts.data_ptr() != verts.data_ptr() and same.faces.data_ptr() != sphere.faces.data_ptr()
    out = simplify_qem(sphere.to(dtype=torch.float64), 0.5)
    assert out.dtype == torch.float64


def test_resolve_target():
    assert resolve_target(0.5, 40000) == 20000
    assert resolve_target(1e-9, 10) == 1
    assert resolve_target(7, 10) == 7
    with pytest.raises(ValueError, match="target"):
        resolve_target(0, 10)
    with pytest.raises(ValueError, match="target"):
        resolve_target(11, 10)
    with pytest.raises(ValueError, match=r"\(0, 1\]"):
        resolve_target(1.5, 10)
    with pytest.raises(ValueError, match=r"\(0, 1\]"):
        resolve_target(float("nan"), 10)
    with pytest.raises(TypeError, match="target"):
        resolve_target(True, 10)
    with pytest.raises(TypeError, match="target"):
        resolve_target("half", 10)  # type: ignore[arg-type]


def test_empty_mesh():
    with pytest.raises(EmptyInputError, match="mesh"):
        simplify_qem(Mesh(torch.zeros(3, 3), torch.zeros(0, 3, dtype=torch.long)), 0.5)


@pytest.mark.parametrize("target", [1, 0.01])
def test_a_target_that_leaves_no_face_is_an_error(target):
    # A closed icosphere asked for 1 face collapses whole: the result had 0 faces and failed later, at the write or
    # in the tracking ("warped_previous: expected a mesh with faces"), found by review.
    small = as_mesh(trimesh.creation.icosphere(subdivisions=1))
    with pytest.raises(EmptyInputError, match=rf"target: {target!r} \(1 of 80 faces\) left no face"):
        simplify_qem(small, target)
    assert simplify_qem(small, 4).num_faces == 4  # 4 faces: a tetrahedron, kept


def test_soups_bad_aggressiveness_and_missed_targets_are_said(sphere):
    # A soup (STL's form) lost half its surface: every edge is a border, so whole triangles went (area 6.19 of 12.57
    # at 50 %); agg NaN or -1 and a small agg missed the target without a word (found by review).
    m = as_mesh(sphere)
    soup = Mesh(m.verts[m.faces.reshape(-1)], torch.arange(m.num_faces * 3).reshape(-1, 3))
    # Corners at exactly the same position are welded (review G): the soup is the sphere, simplified as the sphere is.
    welded, direct = simplify_qem(soup, 0.5), simplify_qem(m, 0.5)
    assert welded.num_faces == direct.num_faces == m.num_faces // 2
    area = trimesh.Trimesh(welded.verts.numpy(), welded.faces.numpy()).area
    assert area == pytest.approx(trimesh.Trimesh(direct.verts.numpy(), direct.faces.numpy()).area, rel=1e-3)
    # Corners that do not coincide (each copy moved by 1e-9) stay a soup: refused, not cut into holes.
    jitter = torch.arange(soup.num_verts, dtype=soup.verts.dtype)[:, None] * 1e-9
    with pytest.raises(ValueError, match=r"mesh: a triangle soup \(\d+ faces, no vertex shared .*merge_vertices"):
        simplify_qem(Mesh(soup.verts + jitter, soup.faces), 0.5)
    for agg in (float("nan"), -1.0, 0, True, "7"):
        with pytest.raises(ValueError, match=r"agg: expected a finite number > 0"):
            simplify_qem(m, 0.5, agg=agg)  # type: ignore[arg-type]
    from torchmeshmetric.data import demo_sequence

    # 1548 faces; agg 2.0 stops at 1242 of 774 (measured; 1222 before the canonical extent 2.0)
    frame = demo_sequence(1, resolution=32).frames[0]
    with pytest.warns(UserWarning, match=r"at 1242 faces, above the target 774 \(agg=2.0 .* default 7.0 reaches 774 "):
        simplify_qem(frame, 774, agg=2.0)


def test_non_finite_vertices_are_refused_not_simplified(sphere):
    # A Mesh built with validate=False skipped the finiteness check, and QEM's output held NaN vertices without a
    # word (found by review, 2026-12-07).
    from torchmeshmetric import NonFiniteError
    from torchmeshmetric.simplification import simplify_registered_qem

    verts = sphere.verts.clone()
    verts[7, 1] = float("nan")
    bad = Mesh(verts, sphere.faces, validate=False)
    with pytest.raises(NonFiniteError, match=r"mesh\.verts: expected finite values, found 1 NaN/Inf"):
        simplify_qem(bad, 0.5)
    with pytest.raises(NonFiniteError, match=r"mesh_k\.verts: expected finite values, found 1 NaN/Inf"):
        simplify_registered_qem(bad, sphere, 0.5, weight=1.0)
    with pytest.raises(NonFiniteError, match=r"registered_mesh_k_minus_1\.verts: expected finite values"):
        simplify_registered_qem(sphere, bad, 0.5, weight=1.0)


def test_duplicate_vertices_are_welded_and_zero_area_faces_dropped():
    # Capture defects' seams of duplicate vertices stopped QEM above its target (fast-simplification never moves a
    # border vertex), and their faces with a repeated corner passed through; QEM now starts from the same welded
    # surface as Registered and Anchored QEM (review G).
    from torchmeshmetric.data import add_capture_defects, demo_sequence

    frame = demo_sequence(1, resolution=64).frames[0]
    d = add_capture_defects(frame, seed=0, duplicate_fraction=0.05)
    target = round(0.03 * frame.num_faces)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the target is met: no miss warning
        out = simplify_qem(d, target)
    f = out.faces
    assert abs(out.num_faces - target) <= 1  # unwelded: 586 faces of 191 (measured by review G)
    assert not bool(((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])).any())


def test_the_result_does_not_depend_on_the_unit_of_the_coordinates():
    # fast-simplification stops at an absolute error threshold: the same frame in 16-bit integer coordinates (x65535)
    # stopped at 1120 faces whatever the target (774, 386 or 154), and the warning blamed agg (found by review G).
    # simplify_qem now simplifies a copy scaled to one canonical extent; a power of two scales the extent and the
    # factor exactly, so the copy is the same to the bit: exactly the same collapses.
    import numpy as np

    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.simplification._canonical_scale import CANONICAL_EXTENT, canonical_factor

    frame = demo_sequence(1, resolution=32).frames[0].to(dtype=torch.float64)  # 1548 faces, 1.83 units tall
    verts, faces = frame.verts.numpy(), frame.faces.numpy()
    s = canonical_factor(verts, faces)
    assert s == CANONICAL_EXTENT / float((verts.max(0) - verts.min(0)).max())  # 2.0 / 1.83: no power of two
    for target in (774, 386, 154):
        unit = simplify_qem(frame, target)
        assert unit.num_faces == target
        for k in (-20, 12, 16, 40):  # a power of two: the same faces, the vertices times 2**k to the bit
            assert canonical_factor(np.ldexp(verts, k), faces) == np.ldexp(s, -k)
            scaled = simplify_qem(Mesh(torch.from_numpy(np.ldexp(verts, k)), frame.faces), target)
            assert torch.equal(scaled.faces, unit.faces)
            assert np.array_equal(scaled.verts.numpy(), np.ldexp(unit.verts.numpy(), k))
        quantised = Mesh(torch.round((frame.verts + 1.1) / 2.2 * 65535), frame.faces)  # a decoder's 16-bit units
        assert simplify_qem(quantised, target).num_faces == target
    # A miss that remains is blamed on its real cause (it blamed agg at its default): here the kept border.
    box = trimesh.creation.box().subdivide().subdivide()
    box.update_faces(box.face_normals[:, 2] < 0.5)  # 160 faces, open at the top
    with pytest.warns(UserWarning, match=r"at 16 faces, above the target 2 \(no edge .* keeps every border vertex"):
        simplify_qem(as_mesh(box), 2, preserve_border=True)


def test_any_unit_change_gives_the_same_faces_and_vertices_within_rounding():
    # Review V: the canonical copy was the frame scaled by a power of two into an extent range [1.5, 3), so x1000
    # (= x1024 * 0.977) reached a canonical copy of another size and other decisions: on this frame at 154 faces other
    # faces at -6.6 % error; demo frame 0 at 9951 faces, inches shared 1.5 % of the faces at -13 %. Now every unit
    # reaches one canonical extent (2.0), the copies differ by rounding only, and the decisions agree.
    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.simplification import qem

    assert "metres, millimetres or integer units gives the same faces" not in (qem.__doc__ or "")
    frame = demo_sequence(1, resolution=32).frames[0]  # float32: its float64 multiples by 1000 are exact
    f64 = frame.to(dtype=torch.float64)
    eps = torch.finfo(torch.float64).eps
    extent = float((f64.verts.max(0).values - f64.verts.min(0).values).max())
    inputs = {tuple(r) for r in f64.verts.numpy().tolist()}
    checked = 0
    for target in (774, 387, 155):
        base = simplify_qem(f64, target)
        kept = torch.tensor([tuple(r) in inputs for r in base.verts.numpy().tolist()])  # rows at an input vertex
        checked += int(kept.sum())  # none at 155 faces: every survivor moved
        for unit in (1000.0, 0.001, 0.0254, 0.3048, 3.7):
            scaled = simplify_qem(Mesh(f64.verts * unit, f64.faces), target)
            assert torch.equal(scaled.faces, base.faces)
            # Moved vertices: the optimal positions of the collapses, solved from quadrics of copies an ulp apart,
            # measured at most 58 eps * extent apart here (36 to 58 at 774 faces, 4 to 10 at 155); 100 leaves room.
            dev = float((scaled.verts - base.verts * unit).abs().max()) / (eps * extent * unit)
            assert dev <= 100.0, (target, unit, dev)
            if unit == 1000.0:  # an exact multiple: a vertex at an input vertex is that input's x1000, to the bit
                assert torch.equal(scaled.verts[kept], base.verts[kept] * unit)
        # The frame rescaled in float32 (rounded there, as a decoder or an exporter would), then simplified: the same
        # faces here, vertices within 2.5e9 eps * extent (4.6 float32 ulps of the extent, measured) of x1000.
        f32 = simplify_qem(Mesh((frame.verts * 1000.0).double(), frame.faces), target)
        assert torch.equal(f32.faces, base.faces)
        assert float((f32.verts - base.verts * 1000.0).abs().max()) <= 4e9 * eps * extent * 1000.0
    assert checked > 0


def test_vertices_that_did_not_move_come_back_with_their_input_bits():
    # The canonical copy is verts * s and s is no power of two (2.0 / extent): out / s put an unmoved vertex up to an
    # ulp off its input. Each output row at the canonical position of an input vertex is that vertex's own row.
    import fast_simplification
    import numpy as np

    from torchmeshmetric.data import demo_sequence
    from torchmeshmetric.simplification._canonical_scale import canonical_factor, original_rows

    frame = demo_sequence(1, resolution=32).frames[0].to(dtype=torch.float64)
    verts, faces = frame.verts.numpy() * 0.0254, frame.faces.numpy()  # inches: a factor far from a power of two
    s = canonical_factor(verts, faces)
    scaled = verts * s
    ov, _, collapses = fast_simplification.simplify(scaled, faces, target_count=387, return_collapses=True)
    survivors = np.setdiff1d(np.unique(faces), collapses[:, 1])
    assert survivors.size == ov.shape[0]
    unmoved = (ov == scaled[survivors]).all(1)
    naive = ov / s
    assert unmoved.any() and not (naive[unmoved] == verts[survivors[unmoved]]).all()  # out / s: not the input bits
    out = simplify_qem(Mesh(torch.from_numpy(verts), frame.faces), 387).verts.numpy()
    assert np.array_equal(out[unmoved], verts[survivors[unmoved]])
    # Moved vertices: the canonical position divided by s, correctly rounded (within half an ulp of it); a moved row
    # that lands on another input vertex's canonical position (a collapse to an end) takes that vertex's bits.
    at_input = {tuple(r): i for i, r in reversed(list(enumerate(scaled.tolist())))}
    for j in np.flatnonzero(~unmoved):
        i = at_input.get(tuple(ov[j].tolist()))
        assert np.array_equal(out[j], naive[j] if i is None else verts[i])
    # Without the row of each output vertex (survivors None), the lookup by position gives the same rows here.
    assert np.array_equal(original_rows(ov, scaled, verts, s, None), out)
    # Two input vertices an ulp apart may round to one canonical position: the first of them is taken.
    v = np.array([[1.9, 1.0, 1.0], [np.nextafter(1.9, 2.0), 1.0, 1.0], [0.0, 0.0, 0.0]])
    s2 = 1.9  # 1.9 * 1.9 and the next double times 1.9 round to the same 3.61
    assert (v[0] * s2 == v[1] * s2).all()
    assert np.array_equal(original_rows(v[1:2] * s2, v * s2, v, s2, None), v[:1])
    assert np.array_equal(original_rows(v[1:2] * s2, v * s2, v, s2, np.array([1])), v[1:2])  # its own row first
