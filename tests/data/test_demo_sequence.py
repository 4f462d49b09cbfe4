import math

import pytest
import torch

from tests.cpu_personalities import OTHER_CPUS, run_as
from torchmeshmetric import IndexRangeError, Mesh, point_mesh_distance
from torchmeshmetric.data import BONE_NAMES, DemoSequence, demo_sequence


@pytest.fixture(scope="module")
def seq() -> DemoSequence:
    return demo_sequence(6, resolution=48)


def test_shapes_and_types(seq):
    k, b = seq.num_frames, len(BONE_NAMES)
    assert seq.rotations.shape == (k, b, 3, 3) and seq.translations.shape == (k, b, 3)
    eye = torch.eye(3, dtype=torch.float64).expand(k, b, 3, 3)
    torch.testing.assert_close(seq.rotations @ seq.rotations.transpose(-1, -2), eye, atol=1e-12, rtol=0)
    torch.testing.assert_close(torch.linalg.det(seq.rotations), torch.ones(k, b, dtype=torch.float64))
    for f in seq.frames:
        assert isinstance(f, Mesh) and f.dtype == torch.float32
        tm = f.to_trimesh()
        assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0  # closed, outward normals
        assert len(tm.split(only_watertight=False)) == 1
        assert float(f.verts.abs().max()) <= 1.05  # normalised to about +-1


def test_deterministic():
    a = demo_sequence(2, resolution=32, seed=5)
    b = demo_sequence(2, resolution=32, seed=5)
    c = demo_sequence(2, resolution=32, seed=6)
    for fa, fb in zip(a.frames, b.frames, strict=True):
        assert torch.equal(fa.verts, fb.verts) and torch.equal(fa.faces, fb.faces)
    assert torch.equal(a.rotations, b.rotations) and torch.equal(a.translations, b.translations)
    assert not torch.equal(a.prim_radius, c.prim_radius)
    assert a.frames[0].num_verts != c.frames[0].num_verts or not torch.equal(a.frames[0].verts, c.frames[0].verts)


def test_frames_meshed_independently(seq):
    counts = [f.num_verts for f in seq.frames]
    assert len(set(counts)) == len(counts)  # every frame has its own vertex count
    for a, b in zip(seq.frames[:-1], seq.frames[1:], strict=True):
        n = min(a.num_faces, b.num_faces)
        assert not torch.equal(a.faces[:n], b.faces[:n])


def test_default_size_is_paper_class():
    """Default resolution: about 20k vertices / 40k faces per frame (the paper's frames: ~20k / ~40k)."""
    frame = demo_sequence(1).frames[0]
    assert 18_000 <= frame.num_verts <= 22_000 and 36_000 <= frame.num_faces <= 44_000
    # faces grow with resolution ** 2
    small = demo_sequence(1, resolution=80).frames[0]
    assert 0.2 <= small.num_faces / frame.num_faces <= 0.3


def test_mesh_lies_on_its_field(seq):
    """Marching-cubes vertices interpolate the field linearly along voxel edges: |f| <= h^2 max|f''| / 8, with
    max|f''| about 1 / (smallest radius). Measured max / (h^2 / (8 r_min)): 1.26 (res 24), 0.98 (48), 1.16 (96)."""
    r_min = float(seq.prim_radius.min())
    errs = {}
    for res, s in ((48, seq), (96, demo_sequence(1, resolution=96))):
        h = 2.0 / res
        err = max(float(s.sdf(f.verts.double(), k).abs().max()) for k, f in enumerate(s.frames))
        assert err < 1.5 * h * h / (8 * r_min)
        errs[res] = err
    assert errs[48] / errs[96] > 3.0  # second-order convergence (measured 3.4)


def test_ground_truth_motion_consistency(seq):
    """Frame k-1's vertices, moved by the ground truth, lie on frame k's surface.

    Measured at resolution 48 on 300 random vertices per pair: mean 0.0009-0.0011, max 0.005-0.012 of the bbox
    diagonal (the max sits in blend regions at joints, where skinning is approximate; the mean includes the
    marching-cubes error); without the motion the mean is 4-16x larger.
    """
    gen = torch.Generator().manual_seed(0)
    diag = float(seq.frames[0].bbox_diagonal())
    for k in range(1, seq.num_frames):
        src = seq.frames[k - 1]
        x = src.verts[torch.randperm(src.num_verts, generator=gen)[:300]].double()
        ref = seq.frames[k].to(dtype=torch.float64)
        moved = point_mesh_distance(seq.transfer(x, k - 1, k), ref).dists / diag
        static = point_mesh_distance(x, ref).dists / diag
        assert float(moved.mean()) < 0.0015
        assert float(moved.max()) < 0.015
        assert float(moved.mean()) < 0.3 * float(static.mean())


def test_transfer_is_rigid_on_single_bones(seq):
    # the top of the head is far (> 0.25) from every primitive of another bone: its weight on them is below
    # exp(-0.25 / blend) ~ 4e-6 (measured 2.9e-7), and it moves with the head bone up to that weight x 2 units
    head = BONE_NAMES.index("head")
    x = seq.frames[0].verts[seq.frames[0].verts[:, 1].argmax()][None].double()
    w = seq.skinning_weights(x, 0)
    assert float(w[0, head]) > 1 - 4e-6
    r0, t0 = seq.rotations[0, head], seq.translations[0, head]
    r1, t1 = seq.rotations[2, head], seq.translations[2, head]
    expected = (r1 @ r0.T @ (x[0] - t0) + t1)[None]
    torch.testing.assert_close(seq.transfer(x, 0, 2), expected, atol=8e-6, rtol=0)
    torch.testing.assert_close(seq.transfer(x, 0, 0), x, atol=1e-12, rtol=0)
    torch.testing.assert_close(w.sum(1), torch.ones(1, dtype=torch.float64))


def test_motion_contains_punch_kick_turn():
    s = demo_sequence(24, resolution=16)
    fist_r = s.prim_a[11]
    bone = int(s.prim_bone[11])
    reach = [(s.rotations[k, bone] @ fist_r + s.translations[k, bone]) for k in range(24)]
    pelvis_yaw = [
        math.degrees(math.atan2(float(s.rotations[k, 0, 0, 2]), float(s.rotations[k, 0, 0, 0]))) for k in range(24)
    ]
    foot_l = [float((s.rotations[k, 9] @ s.prim_b[14] + s.translations[k, 9])[1]) for k in range(24)]
    # punch: the right fist travels forward (in the body frame) at frame 3; kick: the left foot rises; turn: yaw spans
    assert max(float(r[2]) for r in reach[:6]) > 0.4
    assert max(foot_l) - min(foot_l) > 0.5
    assert max(pelvis_yaw) - min(pelvis_yaw) > 150


def test_bad_arguments(seq):
    with pytest.raises(ValueError, match="num_frames"):
        demo_sequence(0)
    with pytest.raises(ValueError, match="resolution"):
        demo_sequence(1, resolution=4)
    with pytest.raises(ValueError, match="blend"):
        demo_sequence(1, blend=0.0)
    with pytest.raises(IndexRangeError, match="dst"):
        seq.transfer(seq.frames[0].verts[:2], 0, 6)
    with pytest.raises(TypeError, match="src"):
        seq.transfer(seq.frames[0].verts[:2], 0.5, 1)


_DIGEST = """
import hashlib
import torch
from torchmeshmetric.data import demo_sequence

seq = demo_sequence(3, resolution=24, seed=1, frames_per_cycle=5)
h = hashlib.sha256()
for f in seq.frames:
    h.update(f.verts.numpy().tobytes())
    h.update(f.faces.numpy().tobytes())
x = seq.frames[0].verts[::7].double()
for t in (seq.rotations, seq.translations, seq.sdf(x, 1), seq.skinning_weights(x, 2), seq.transfer(x, 0, 2)):
    h.update(t.numpy().tobytes())
print(h.hexdigest())
"""


@pytest.mark.pinned
@pytest.mark.parametrize("personality", sorted(OTHER_CPUS))
def test_same_bits_on_every_cpu(personality):
    """The built-in sequence (frames, motion, field, skinning) is the same bits under every CPU personality (issue 38).

    Before, numpy's per-instruction-set float32 exp/log and BLAS moved 3 to 5 vertices a frame by float32 ulps.
    """
    assert run_as(OTHER_CPUS[personality], _DIGEST) == run_as({}, _DIGEST)


@pytest.mark.pinned
def test_float64_frames_round_to_the_float32_frames():
    a = demo_sequence(2, resolution=24)
    b = demo_sequence(2, resolution=24, dtype=torch.float64)
    for fa, fb in zip(a.frames, b.frames, strict=True):
        assert fb.dtype == torch.float64 and torch.equal(fb.faces, fa.faces)
        assert torch.equal(fb.verts.float(), fa.verts)  # one rounding apart
        assert not torch.equal(fb.verts, fa.verts.double())
    with pytest.raises(TypeError, match="dtype"):
        demo_sequence(1, resolution=16, dtype=torch.int64)
