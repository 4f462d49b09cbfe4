r"""Built-in volumetric-video-like demo sequence: a procedural performer doing a martial-arts-like motion.

The performer is a stick-figure skeleton of 13 rigid bones (pelvis, spine, head, upper/lower arms, thighs, shins,
feet) dressed with 18 capsules (spheres for the head and fists). Its surface is the zero level set of the signed
distance field

.. math::

    f(x) = -k \log \sum_i \exp(-d_i(x) / k),

the exponential smooth union (smooth minimum) of the primitives' signed distances :math:`d_i`, with blend radius
:math:`k`. Each frame poses the skeleton by forward kinematics from key poses (guard, punches, kicks, turns) and is
meshed **independently** with marching cubes (Lorensen & Cline 1987; scikit-image's Lewiner variant), on a narrow band
found coarse-to-fine, so connectivity and vertex count differ per frame, as in captured volumetric video.

Ground truth: every bone's rigid transform per frame is known. A surface point is skinned to the bones with the same
soft-min weights :math:`w_i = \exp(-d_i/k) / \sum_j \exp(-d_j/k)` that blend the field, and moved by linear
blend skinning (:meth:`DemoSequence.transfer`). Points on a single primitive move exactly; points in a blend region
(around joints) move approximately (see docs/data.md for the measured error).

Everything is procedural: no asset, no download, no licence beyond the library's own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from skimage.measure import marching_cubes
from torch import Tensor

from torchmeshmetric._checks import (
    IndexRangeError,
    check_allocation,
    check_finite,
    check_float,
    check_float_dtype,
    check_int,
    check_shape,
)
from torchmeshmetric.data._portable_math import cos_deg, dot3, exp, log, matmul3, matvec3, sin_deg
from torchmeshmetric.structures import Mesh

__all__ = ["BONE_NAMES", "DemoSequence", "demo_sequence"]

# --------------------------------------------------------------------------------------------------------------------
# Skeleton (rest pose, y up, performer faces +z, left side at +x). Units: about +-1 overall.
# --------------------------------------------------------------------------------------------------------------------
BONE_NAMES: tuple[str, ...] = (
    "pelvis",
    "spine",
    "head",
    "upper_arm_l",
    "forearm_l",
    "upper_arm_r",
    "forearm_r",
    "thigh_l",
    "shin_l",
    "foot_l",
    "thigh_r",
    "shin_r",
    "foot_r",
)
"""Names of the performer's rigid bones, in the order of :attr:`DemoSequence.rotations`."""

_PARENT = (-1, 0, 1, 1, 3, 1, 5, 0, 7, 8, 0, 10, 11)
# Joint (pivot) of each bone in the rest pose.
_JOINT = np.array(
    [
        [0.0, 0.0, 0.0],  # pelvis
        [0.0, 0.18, 0.0],  # spine (waist)
        [0.0, 0.62, 0.0],  # head (neck base)
        [0.2, 0.54, 0.0],  # upper_arm_l (shoulder)
        [0.23, 0.26, 0.0],  # forearm_l (elbow)
        [-0.2, 0.54, 0.0],
        [-0.23, 0.26, 0.0],
        [0.1, -0.06, 0.0],  # thigh_l (hip)
        [0.11, -0.5, 0.0],  # shin_l (knee)
        [0.11, -0.9, 0.0],  # foot_l (ankle)
        [-0.1, -0.06, 0.0],
        [-0.11, -0.5, 0.0],
        [-0.11, -0.9, 0.0],
    ]
)
# Primitives: (bone, a, b, radius); a == b makes a sphere.
_PRIMS: tuple[tuple[int, tuple[float, float, float], tuple[float, float, float], float], ...] = (
    (0, (-0.09, -0.04, 0.0), (0.09, -0.04, 0.0), 0.11),  # hips
    (0, (0.0, -0.02, 0.0), (0.0, 0.18, 0.0), 0.13),  # belly
    (1, (0.0, 0.2, 0.0), (0.0, 0.44, 0.01), 0.14),  # chest
    (1, (-0.15, 0.5, 0.0), (0.15, 0.5, 0.0), 0.075),  # shoulder girdle
    (2, (0.0, 0.58, 0.0), (0.0, 0.7, 0.01), 0.05),  # neck
    (2, (0.0, 0.8, 0.02), (0.0, 0.8, 0.02), 0.11),  # head
    (3, (0.2, 0.54, 0.0), (0.23, 0.26, 0.0), 0.052),  # upper arm l
    (4, (0.23, 0.26, 0.0), (0.255, 0.03, 0.0), 0.043),  # forearm l
    (4, (0.26, -0.04, 0.0), (0.26, -0.04, 0.0), 0.05),  # fist l
    (5, (-0.2, 0.54, 0.0), (-0.23, 0.26, 0.0), 0.052),
    (6, (-0.23, 0.26, 0.0), (-0.255, 0.03, 0.0), 0.043),
    (6, (-0.26, -0.04, 0.0), (-0.26, -0.04, 0.0), 0.05),
    (7, (0.1, -0.06, 0.0), (0.11, -0.5, 0.0), 0.08),  # thigh l
    (8, (0.11, -0.5, 0.0), (0.11, -0.9, 0.0), 0.058),  # shin l
    (9, (0.11, -0.93, -0.03), (0.11, -0.95, 0.15), 0.042),  # foot l
    (10, (-0.1, -0.06, 0.0), (-0.11, -0.5, 0.0), 0.08),
    (11, (-0.11, -0.5, 0.0), (-0.11, -0.9, 0.0), 0.058),
    (12, (-0.11, -0.93, -0.03), (-0.11, -0.95, 0.15), 0.042),
)

# Key poses: phase in [0, 1), root yaw (deg), root height offset, and per-bone local Euler angles (deg, x then y then
# z applied as Rz @ Ry @ Rx). Negative x on a limb hanging down swings it forward (+z).
_GUARD = {
    "spine": (5.0, 0.0, 0.0),
    "upper_arm_l": (-55.0, 0.0, 15.0),
    "forearm_l": (-110.0, 0.0, 0.0),
    "upper_arm_r": (-45.0, 0.0, -15.0),
    "forearm_r": (-115.0, 0.0, 0.0),
    "thigh_l": (-25.0, 0.0, 8.0),
    "shin_l": (30.0, 0.0, 0.0),
    "foot_l": (-5.0, 0.0, 0.0),
    "thigh_r": (10.0, 0.0, -8.0),
    "shin_r": (25.0, 0.0, 0.0),
    "foot_r": (-15.0, 0.0, 0.0),
}


def _pose(**over: tuple[float, float, float]) -> dict[str, tuple[float, float, float]]:
    d = dict(_GUARD)
    d.update(over)
    return d


_KEYS: tuple[tuple[float, float, float, dict[str, tuple[float, float, float]]], ...] = (
    (0.0, 0.0, -0.04, _pose()),
    # right straight punch, torso twists into it
    (0.125, -10.0, -0.05, _pose(spine=(5.0, -25.0, 0.0), upper_arm_r=(-88.0, 0.0, 8.0), forearm_r=(-5.0, 0.0, 0.0))),
    (0.25, 20.0, -0.04, _pose()),
    # left front kick
    (
        0.375,
        45.0,
        0.0,
        _pose(thigh_l=(-95.0, 0.0, 0.0), shin_l=(15.0, 0.0, 0.0), foot_l=(35.0, 0.0, 0.0), shin_r=(10.0, 0.0, 0.0)),
    ),
    (0.5, 90.0, -0.04, _pose()),
    # left jab
    (0.625, 110.0, -0.05, _pose(spine=(5.0, 20.0, 0.0), upper_arm_l=(-88.0, 0.0, -8.0), forearm_l=(-5.0, 0.0, 0.0))),
    # right roundhouse kick while turning
    (
        0.75,
        200.0,
        0.0,
        _pose(
            spine=(0.0, 0.0, 20.0),
            thigh_r=(-60.0, 0.0, -70.0),
            shin_r=(30.0, 0.0, 0.0),
            foot_r=(30.0, 0.0, 0.0),
            thigh_l=(0.0, 0.0, 5.0),
            shin_l=(10.0, 0.0, 0.0),
        ),
    ),
    (0.875, 300.0, -0.04, _pose()),
    (1.0, 360.0, -0.04, _pose()),
)


def _euler(deg: np.ndarray) -> np.ndarray:
    """``(..., 3)`` Euler angles in degrees -> ``(..., 3, 3)`` rotation ``Rz @ Ry @ Rx``."""
    a, b, c = deg[..., 0], deg[..., 1], deg[..., 2]
    ca, sa, cb, sb, cc, sc = cos_deg(a), sin_deg(a), cos_deg(b), sin_deg(b), cos_deg(c), sin_deg(c)
    one, zero = np.ones_like(a), np.zeros_like(a)
    rx = np.stack([one, zero, zero, zero, ca, -sa, zero, sa, ca], -1).reshape(*a.shape, 3, 3)
    ry = np.stack([cb, zero, sb, zero, one, zero, -sb, zero, cb], -1).reshape(*a.shape, 3, 3)
    rz = np.stack([cc, -sc, zero, sc, cc, zero, zero, zero, one], -1).reshape(*a.shape, 3, 3)
    return matmul3(matmul3(rz, ry), rx)


def _key_arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    phases = np.array([k[0] for k in _KEYS])
    yaw = np.array([k[1] for k in _KEYS])
    height = np.array([k[2] for k in _KEYS])
    angles = np.zeros((len(_KEYS), len(BONE_NAMES), 3))
    for i, (_, _, _, pose) in enumerate(_KEYS):
        for name, eul in pose.items():
            angles[i, BONE_NAMES.index(name)] = eul
    return phases, yaw, height, angles


def _pose_at(phase: float, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics at ``phase``: per-bone world ``R (B, 3, 3)`` and ``t (B, 3)`` with ``x -> R x + t``."""
    phases, yaw, height, angles = _key_arrays()
    ph = phase % 1.0
    i = int(np.searchsorted(phases, ph, side="right")) - 1
    i = min(i, len(phases) - 2)
    u = (ph - phases[i]) / (phases[i + 1] - phases[i])
    s = u * u * (3.0 - 2.0 * u)  # smoothstep: velocity 0 at key poses
    ang = (1 - s) * angles[i] + s * angles[i + 1]
    root_yaw = (1 - s) * yaw[i] + s * yaw[i + 1]
    root_y = (1 - s) * height[i] + s * height[i + 1]
    local = _euler(ang)
    num_bones = len(BONE_NAMES)
    rot = np.zeros((num_bones, 3, 3))
    pos = np.zeros((num_bones, 3))  # world position of each joint
    for b in range(num_bones):
        p = _PARENT[b]
        if p < 0:
            rot[b] = matmul3(_euler(np.array([0.0, root_yaw, 0.0])), local[b])
            pos[b] = joints[b] + np.array([0.0, root_y, 0.0])
        else:
            rot[b] = matmul3(rot[p], local[b])
            pos[b] = matvec3(rot[p], joints[b] - joints[p]) + pos[p]
    trans = pos - matvec3(rot, joints)
    return rot, trans


def _capsule_dists(x: np.ndarray, a: np.ndarray, b: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Signed distances ``(P, M)`` from points ``(P, 3)`` to capsules ``a, b (M, 3)``, radii ``(M,)``."""
    out = np.empty((x.shape[0], a.shape[0]), dtype=x.dtype)
    for m in range(a.shape[0]):
        ab = b[m] - a[m]
        ax = x - a[m]
        denom = float(dot3(ab, ab))
        t = np.clip(dot3(ax, ab) / denom, 0.0, 1.0) if denom > 0 else np.zeros(x.shape[0], dtype=x.dtype)
        d = ax - t[:, None] * ab
        out[:, m] = np.sqrt(dot3(d, d)) - r[m]
    return out


def _soft_min_terms(d: np.ndarray, k: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``min_i d_i``, the terms ``exp(-(d_i - min) / k)`` and their sum (summed in primitive order)."""
    dmin = d.min(axis=1)
    terms = exp(-(d - dmin[:, None]) / k)
    total = terms[:, 0].copy()
    for m in range(1, terms.shape[1]):  # a fixed order: numpy's reductions may vectorise it per CPU
        total += terms[:, m]
    return dmin, terms, total


def _smooth_union(d: np.ndarray, k: float) -> np.ndarray:
    """Exponential smooth minimum over the last axis, ``-k log sum exp(-d/k)`` (stable)."""
    dmin, _, total = _soft_min_terms(d, k)
    return dmin - k * log(total)


@dataclass(frozen=True, eq=False)
class DemoSequence:
    """The built-in sequence and its ground-truth motion (see :func:`demo_sequence`).

    Attributes:
        frames: the ``K`` meshes, each meshed independently (own connectivity and vertex count), float32.
        rotations: ``(K, B, 3, 3)`` float64 world rotation of each bone per frame (rest pose -> frame).
        translations: ``(K, B, 3)`` float64 translation; a rest-pose point ``x`` of bone ``b`` lies at
            ``rotations[k, b] @ x + translations[k, b]`` in frame ``k``.
        phases: ``(K,)`` float64 phase of each frame in the motion cycle ``[0, 1)``.
        prim_a: ``(M, 3)`` float64 rest-pose first end of each capsule primitive.
        prim_b: ``(M, 3)`` float64 rest-pose second end (equal to ``prim_a`` for a sphere).
        prim_radius: ``(M,)`` float64 radii.
        prim_bone: ``(M,)`` int64 bone of each primitive.
        blend: smooth-union radius ``k`` of the field.
        bone_names: names of the ``B`` bones.

    Example:
        >>> seq = demo_sequence(2, resolution=16)  # a coarse mesh: 16 steps of the marching cubes
        >>> len(seq.frames), tuple(seq.rotations.shape), seq.bone_names[:3], seq.phases.tolist()
        (2, (2, 13, 3, 3), ('pelvis', 'spine', 'head'), [0.0, 0.041666666666666664])
    """

    frames: list[Mesh]
    rotations: Tensor
    translations: Tensor
    phases: Tensor
    prim_a: Tensor
    prim_b: Tensor
    prim_radius: Tensor
    prim_bone: Tensor
    blend: float
    bone_names: tuple[str, ...] = BONE_NAMES

    @property
    def num_frames(self) -> int:
        """Number of frames ``K``."""
        return len(self.frames)

    def _check_frame(self, k: int, name: str) -> int:
        k = check_int(k, name)
        if not -self.num_frames <= k < self.num_frames:
            raise IndexRangeError(f"{name}: frame {k} is out of range for a sequence of {self.num_frames} frames")
        return k % self.num_frames

    def _prim_dists(self, points: np.ndarray, k: int) -> np.ndarray:
        rot = self.rotations[k].numpy()
        tr = self.translations[k].numpy()
        bone = self.prim_bone.numpy()
        a = matvec3(rot[bone], self.prim_a.numpy()) + tr[bone]
        b = matvec3(rot[bone], self.prim_b.numpy()) + tr[bone]
        return _capsule_dists(points, a, b, self.prim_radius.numpy())

    def _points(self, points: Tensor) -> np.ndarray:
        check_shape(points, ("P", 3), "points")
        check_float(points, "points")
        check_finite(points, "points")
        return points.detach().cpu().double().numpy()

    def sdf(self, points: Tensor, frame: int) -> Tensor:
        """Signed distance field of frame ``frame`` at ``points (P, 3)`` (negative inside); ``(P,)``.

        The smooth union is 1-Lipschitz, so ``|sdf|`` is a lower bound of the distance to the surface.
        """
        k = self._check_frame(frame, "frame")
        x = self._points(points)
        return torch.from_numpy(_smooth_union(self._prim_dists(x, k), self.blend)).to(points)

    def skinning_weights(self, points: Tensor, frame: int) -> Tensor:
        """Soft-min skinning weights ``(P, B)`` of ``points`` posed as in ``frame`` (rows sum to 1)."""
        k = self._check_frame(frame, "frame")
        _, w, total = _soft_min_terms(self._prim_dists(self._points(points), k), self.blend)
        w /= total[:, None]
        out = np.zeros((w.shape[0], len(self.bone_names)))
        for m, b in enumerate(self.prim_bone.tolist()):  # in primitive order, as the field sums them
            out[:, b] += w[:, m]
        return torch.from_numpy(out).to(points)

    def transfer(self, points: Tensor, src: int, dst: int) -> Tensor:
        """Ground-truth motion: where surface ``points (P, 3)`` of frame ``src`` are in frame ``dst``.

        Linear blend skinning with the field's own soft-min weights:
        ``x_dst = sum_b w_b(x_src) (R_b^dst (R_b^src)^T (x_src - t_b^src) + t_b^dst)``. Exact for points on a single
        primitive; approximate in blend regions around joints.

        Returns:
            ``(P, 3)`` positions in frame ``dst``, same dtype/device as ``points``.

        Example:
            >>> seq = demo_sequence(2, resolution=40)
            >>> x = seq.frames[0].verts[:5]
            >>> seq.transfer(x, 0, 1).shape
            torch.Size([5, 3])
            >>> bool(torch.allclose(seq.transfer(x, 0, 0), x, atol=1e-6))
            True
        """
        s = self._check_frame(src, "src")
        t = self._check_frame(dst, "dst")
        x = self._points(points)
        w = self.skinning_weights(points.detach().cpu().double(), s).numpy()
        rs, ts = self.rotations[s].numpy(), self.translations[s].numpy()
        rd, td = self.rotations[t].numpy(), self.translations[t].numpy()
        rel = matmul3(rd, rs.transpose(0, 2, 1))  # (B, 3, 3)
        off = td - matvec3(rel, ts)  # (B, 3)
        moved = matvec3(rel[None], x[:, None, :]) + off[None]  # (P, B, 3)
        out = w[:, 0, None] * moved[:, 0]
        for b in range(1, w.shape[1]):  # summed in bone order (see _soft_min_terms)
            out += w[:, b, None] * moved[:, b]
        return torch.from_numpy(out).to(points)


_TOP_BLOCK = 8  # voxels per side of the coarsest blocks of the narrow band (the grid is a whole number of them)
_BYTES_PER_GRID_POINT = 6  # live at once while a frame is meshed: its float32 field and two boolean masks


def _frame_grid(
    rot: np.ndarray,
    trans: np.ndarray,
    prims: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    h: float,
    offset: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A posed frame's capsule ends ``a``, ``b`` ``(P, 3)``, its grid's corner ``lo`` ``(3,)`` and blocks per axis."""
    bone, pa, pb, rad = prims
    a = matvec3(rot[bone], pa) + trans[bone]
    b = matvec3(rot[bone], pb) + trans[bone]
    lo = np.minimum(a, b).min(0) - rad.max() - 3 * h - offset
    hi = np.maximum(a, b).max(0) + rad.max() + 3 * h
    return a, b, lo, np.ceil((hi - lo) / (h * _TOP_BLOCK)).astype(int)


def _check_sizes(num_frames: int, resolution: int, phases: list[float], joints: np.ndarray, prims: tuple) -> None:
    """Refuse, before any frame is meshed, sizes that cannot fit in memory (naming ``resolution`` or ``num_frames``).

    ``phases``: the distinct poses' phases (the motion repeats every ``frames_per_cycle`` frames). The largest
    frame's grid is exact (the sub-voxel offset, ``< h``, left out can only enlarge it); the frames' faces are
    counted at least ``resolution ** 2`` per frame (the least over a motion cycle, measured: 1.08 r**2 at r = 16,
    1.5 r**2 at r = 40, about 1.56 r**2 at 160), 24 bytes each (three int64 indices). ``demo --resolution 99999``
    failed in numpy ("Unable to allocate 693. TiB"), and ``demo --frames 99999999999999999999`` grew to 21.7 GB
    and was killed by the kernel (review X, F11).
    """
    h = 2.0 / resolution
    zero = np.zeros(3)
    points = max(
        float(np.prod((_frame_grid(*_pose_at(ph, joints), prims, h, zero)[3] * _TOP_BLOCK + 1).astype(float)))
        for ph in phases
    )
    check_allocation(points, _BYTES_PER_GRID_POINT, "resolution", resolution, "grid points per frame")
    check_allocation(float(num_frames) * resolution**2, 24, "num_frames", num_frames, "faces")


def _mesh_frame(
    rot: np.ndarray,
    trans: np.ndarray,
    prims: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    h: float,
    blend: float,
    offset: np.ndarray,
    dtype: torch.dtype,
) -> Mesh:
    """Marching cubes of the smooth-union field, evaluated on a narrow band found coarse-to-fine.

    Blocks of 8, then 4, then 2 voxels: the field is 1-Lipschitz, so a block whose centre value exceeds its
    half-diagonal plus a margin of 2 voxels (more than a cube diagonal) holds no surface, and no cube that the surface
    crosses has a corner in it. Only the voxels of the finest active blocks are evaluated exactly; the rest of the
    grid takes the (correctly signed) value of its smallest evaluated enclosing block.
    """
    rad = prims[3]
    a, b, lo, nb = _frame_grid(rot, trans, prims, h, offset)

    def field(idx: np.ndarray, size: int) -> np.ndarray:
        return _smooth_union(_capsule_dists(lo + (idx + 0.5 * size) * h, a, b, rad), blend)

    top = _TOP_BLOCK
    n = nb * top + 1  # grid points per axis
    vol = np.empty(n, dtype=np.float32)
    blocks = np.stack(np.meshgrid(*[np.arange(m) for m in nb], indexing="ij"), -1).reshape(-1, 3) * top
    size = top
    child = np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), -1).reshape(-1, 3)
    while True:
        val = field(blocks, size)
        # Fill the closed block with its centre value (finer levels overwrite where they evaluate).
        span = np.arange(size + 1)
        off = np.stack(np.meshgrid(span, span, span, indexing="ij"), -1).reshape(-1, 3)
        pts = (blocks[:, None, :] + off[None]).reshape(-1, 3)
        vol[pts[:, 0], pts[:, 1], pts[:, 2]] = np.repeat(val.astype(np.float32), off.shape[0])
        keep = np.abs(val) < (0.5 * np.sqrt(3.0) * size + 2.0) * h
        blocks = blocks[keep]
        if size == 2:
            break
        size //= 2
        blocks = (blocks[:, None, :] + size * child[None]).reshape(-1, 3)
    span = np.arange(3)
    off = np.stack(np.meshgrid(span, span, span, indexing="ij"), -1).reshape(-1, 3)
    mask = np.zeros(n, dtype=bool)
    pts = (blocks[:, None, :] + off[None]).reshape(-1, 3)
    mask[pts[:, 0], pts[:, 1], pts[:, 2]] = True
    fine = np.stack(np.nonzero(mask), -1)
    vol[mask] = _smooth_union(_capsule_dists(lo + fine * h, a, b, rad), blend)  # float64, rounded once
    # Marching cubes only in cubes whose 8 corners were evaluated exactly.
    cube = mask[:-1, :-1, :-1].copy()
    for dx, dy, dz in child[1:]:
        cube &= mask[dx : n[0] - 1 + dx, dy : n[1] - 1 + dy, dz : n[2] - 1 + dz]
    full = np.zeros(n, dtype=bool)
    full[:-1, :-1, :-1] = cube
    verts, faces, _, _ = marching_cubes(vol, 0.0, spacing=(h, h, h), allow_degenerate=False, mask=full)
    verts = verts.astype(np.float64) + lo
    faces = faces.astype(np.int64)
    tri = verts[faces]
    signed_volume = dot3(tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()
    if signed_volume < 0:  # outward normals
        faces = faces[:, ::-1].copy()
    return Mesh(torch.from_numpy(verts).to(dtype), torch.from_numpy(faces), validate=False)


def demo_sequence(
    num_frames: int = 6,
    *,
    resolution: int = 160,
    seed: int = 0,
    frames_per_cycle: int = 24,
    start_phase: float = 0.0,
    blend: float = 0.02,
    dtype: torch.dtype = torch.float32,
) -> DemoSequence:
    """Generate the built-in volumetric-video-like sequence (a performer doing kicks, punches and turns).

    Each frame is meshed independently with marching cubes, so vertex count and connectivity differ per frame. The
    default (``resolution=160``) gives about 20k vertices / 40k faces per frame; face count grows with
    ``resolution ** 2``. Deterministic: the same arguments give identical tensors, on every CPU — the field and the
    motion are computed with operations IEEE 754 defines to the bit (:mod:`torchmeshmetric.data._portable_math`),
    never with the per-instruction-set ``exp``/``sin`` kernels or BLAS, and rounded once to ``dtype``.

    Args:
        num_frames: number of frames ``K >= 1``.
        resolution: voxels per 2 units (the performer is about 1.9 units tall); ``>= 16``.
        seed: varies body proportions (+-5 %) and the sub-voxel grid offset of each frame.
        frames_per_cycle: frames per full motion cycle (guard, right punch, front kick, jab, roundhouse kick,
            turning 360 degrees); ``>= 2``. The default 6 frames show a right straight punch.
        start_phase: phase of frame 0 in ``[0, 1)``.
        blend: smooth-union radius ``k`` (> 0) of the field.
        dtype: the frames' vertex dtype: ``torch.float32`` (the default) as captured frames are stored, or
            ``torch.float64`` for the same positions before that rounding (how much a figure depends on the input's
            precision: docs/statistics.md).

    Returns:
        :class:`DemoSequence` with the frames and their ground-truth motion.

    Raises:
        ValueError: an argument is out of range.
        SizeLimitError: ``resolution`` or ``num_frames`` asks for more memory than this machine has (a frame's
            marching-cubes grid, the frames' faces), refused before any frame is made.
        TypeError: a count (``num_frames``, ``resolution``, ``frames_per_cycle``) is not an int.

    Example:
        >>> seq = demo_sequence(3, resolution=40)
        >>> len(seq.frames), seq.rotations.shape
        (3, torch.Size([3, 13, 3, 3]))
        >>> seq.frames[0].num_verts != seq.frames[1].num_verts
        True
    """
    num_frames = check_int(num_frames, "num_frames", 1)
    resolution = check_int(resolution, "resolution", 16)
    frames_per_cycle = check_int(frames_per_cycle, "frames_per_cycle", 2)
    if not np.isfinite(start_phase):
        raise ValueError(f"start_phase: expected a finite float, found {start_phase!r}")
    if not (np.isfinite(blend) and blend > 0):
        raise ValueError(f"blend: expected a float > 0, found {blend!r}")
    check_float_dtype(dtype)
    rng = np.random.default_rng(seed)
    scale = 1.0 + 0.05 * (2 * rng.random(len(BONE_NAMES)) - 1)  # per-bone length scale
    rscale = 1.0 + 0.05 * (2 * rng.random(len(_PRIMS)) - 1)  # per-primitive radius scale
    # Rest joints and primitives with scaled bone lengths (each bone scales about its own joint; children follow).
    joints = _JOINT.copy()
    for bb in range(1, len(BONE_NAMES)):
        p = _PARENT[bb]
        joints[bb] = joints[p] + scale[p] * (_JOINT[bb] - _JOINT[p])
    bone = np.array([p[0] for p in _PRIMS], dtype=np.int64)
    pa = np.array([p[1] for p in _PRIMS]) - _JOINT[bone]
    pb = np.array([p[2] for p in _PRIMS]) - _JOINT[bone]
    pa = joints[bone] + scale[bone, None] * pa
    pb = joints[bone] + scale[bone, None] * pb
    rad = np.array([p[3] for p in _PRIMS]) * rscale
    prims = (bone, pa, pb, rad)
    cycle = min(num_frames, frames_per_cycle)  # the poses repeat after one cycle
    _check_sizes(num_frames, resolution, [(start_phase + i / frames_per_cycle) % 1.0 for i in range(cycle)], joints,
                 prims)  # fmt: skip
    h = 2.0 / resolution
    phases = np.array([(start_phase + i / frames_per_cycle) % 1.0 for i in range(num_frames)])
    rots, trs, frames = [], [], []
    for i in range(num_frames):
        rot, tr = _pose_at(float(phases[i]), joints)
        offset = rng.random(3) * h
        frames.append(_mesh_frame(rot, tr, prims, h, blend, offset, dtype))
        rots.append(rot)
        trs.append(tr)
    return DemoSequence(
        frames=frames,
        rotations=torch.from_numpy(np.stack(rots)),
        translations=torch.from_numpy(np.stack(trs)),
        phases=torch.from_numpy(phases),
        prim_a=torch.from_numpy(pa),
        prim_b=torch.from_numpy(pb),
        prim_radius=torch.from_numpy(rad),
        prim_bone=torch.from_numpy(bone),
        blend=float(blend),
    )
