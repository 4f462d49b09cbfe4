"""Mesh container, as_mesh conversions and packing."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
import trimesh

from torchmeshmetric import (
    DTypeError,
    IndexRangeError,
    Mesh,
    NonFiniteError,
    ShapeError,
    as_mesh,
    pack_meshes,
    pack_points,
)


def test_as_mesh_accepts_all_forms() -> None:
    tm = trimesh.creation.box()
    forms = [tm, (tm.vertices, tm.faces), (torch.tensor(tm.vertices), torch.tensor(tm.faces)), as_mesh(tm)]
    meshes = [as_mesh(f) for f in forms]
    for m in meshes:
        assert torch.equal(m.verts, torch.tensor(tm.vertices)) and torch.equal(m.faces, torch.tensor(tm.faces))
        assert m.faces.dtype == torch.int64
    assert as_mesh(meshes[0]) is meshes[0]
    assert as_mesh(tm, dtype=torch.float32).dtype == torch.float32


def test_mesh_is_immutable_and_round_trips_trimesh() -> None:
    m = as_mesh(trimesh.creation.icosphere(subdivisions=1))
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.verts = torch.zeros(1, 3)  # type: ignore[misc]
    back = m.to_trimesh()
    np.testing.assert_array_equal(back.vertices, m.verts.numpy())
    np.testing.assert_array_equal(back.faces, m.faces.numpy())
    assert float(m.bbox_diagonal()) == pytest.approx(float(np.linalg.norm(np.ptp(back.vertices, axis=0))))
    assert float(m.face_areas().sum()) == pytest.approx(back.area)


def test_mesh_validation_errors() -> None:
    with pytest.raises(ShapeError, match=r"verts: expected shape \(V, 3\), found \(3, 2\)"):
        Mesh(torch.zeros(3, 2), torch.zeros(1, 3, dtype=torch.long))
    with pytest.raises(DTypeError, match="verts"):
        Mesh(torch.zeros(3, 3, dtype=torch.int32), torch.zeros(1, 3, dtype=torch.long))
    with pytest.raises(NonFiniteError, match="verts"):
        Mesh(torch.full((3, 3), float("nan")), torch.zeros(1, 3, dtype=torch.long))
    with pytest.raises(IndexRangeError, match="faces"):
        Mesh(torch.zeros(3, 3), torch.tensor([[0, 1, 3]]))
    with pytest.raises(ShapeError, match=r"mesh\.verts"):
        as_mesh((np.zeros((3, 4)), np.zeros((1, 3), dtype=int)))
    with pytest.raises(TypeError, match="mesh: expected a Mesh"):
        as_mesh([1, 2, 3])  # type: ignore[arg-type]


def test_pack_meshes_and_points() -> None:
    a, b = as_mesh(trimesh.creation.box()), as_mesh(trimesh.creation.icosphere(subdivisions=0))
    p = pack_meshes([a, b])
    assert p.verts_lengths.tolist() == [8, 12] and p.faces_lengths.tolist() == [12, 20]
    assert torch.equal(p.faces[12:], b.faces)  # faces stay local to their item
    q = pack_points([torch.zeros(2, 3), torch.ones(5, 3)])
    assert q.lengths.tolist() == [2, 5] and q.points.shape == (7, 3)
    with pytest.raises(ShapeError, match="points_lengths: expected lengths summing to 7"):
        pack_points(q.points, torch.tensor([2, 4]))
    with pytest.raises(IndexRangeError, match="packed face 12"):
        pack_meshes(p.verts, p.faces + torch.tensor([0] * 12 + [8] * 20)[:, None], p.verts_lengths, p.faces_lengths)
