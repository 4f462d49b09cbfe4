"""``topology_equivalence`` / ``read_topology_map`` without the oracle, and ``torchmeshmetric mpeg --mode topo``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from torchmeshmetric.cli import main
from torchmeshmetric.mpeg import TopologyMapError, read_topology_map, topology_equivalence

QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
V = torch.tensor([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
A = (V, torch.tensor([[0, 1, 2], [0, 2, 3]]))


def test_read_map_as_mmetric(tmp_path: Path) -> None:
    p = tmp_path / "m.txt"
    p.write_text("  1\t0 extra words\r\n+0 2\n")  # whitespace, \r, a sign and trailing text are read as mm reads them
    assert read_topology_map(p, 3).tolist() == [2, 0, -1]
    p.write_text("0 1\n-1 0\n")  # a negative index wraps (size_t), so it is out of range
    with pytest.raises(TopologyMapError, match=r"m\.txt:2: face index 18446744073709551615 \(column 1, mesh B\)"):
        read_topology_map(p, 3)
    p.write_text("0 1\n1 0\n\n")  # the empty line after the last newline is a line
    with pytest.raises(TopologyMapError, match=r"m\.txt:3: expected two unsigned face indices"):
        read_topology_map(p, 3)
    p.write_text("0 1\n0 2\n")
    with pytest.raises(TopologyMapError, match=r"m\.txt:2: face 0 of mesh B is already mapped to face 1 of mesh A"):
        read_topology_map(p, 3)
    with pytest.raises(TopologyMapError, match=r"vertex map file .*none\.txt.*cannot read"):
        read_topology_map(tmp_path / "none.txt", 3, "vertex")


def test_verdicts() -> None:
    b = (V[[3, 2, 1, 0]], torch.tensor([[1, 0, 3], [3, 2, 1]]))  # faces swapped, vertices reversed
    vmap = torch.tensor([3, 2, 1, 0])
    assert topology_equivalence(A, b, torch.tensor([1, 0]), vmap).matching
    flipped = (b[0], torch.tensor([[0, 1, 3], [3, 2, 1]]))
    r = topology_equivalence(A, flipped, torch.tensor([1, 0]), vmap)
    assert (r.matching, r.reason, r.face_b, r.face_a, r.corners_a, r.corners_b) == (
        False,
        "orientation",
        0,
        1,
        (0, 2, 3),
        (3, 2, 0),
    )
    assert r.report().splitlines()[1:] == [
        "modelA->Triangle[1] = [0,2,3)].",
        "modelB(with mapped indices from modelA)->Triangle[0] = [3,2,0)].",
    ]
    r = topology_equivalence(A, b, torch.tensor([1, -1]), vmap)
    assert (r.reason, r.first_unmapped) == ("face map", 1)
    r = topology_equivalence(A, b, torch.tensor([1, 0]), torch.tensor([3, -1, 1, 0]))
    assert (r.reason, r.first_unmapped) == ("vertex map", 1)
    r = topology_equivalence(A, (V, A[1][:1]), "never read.txt", "never read.txt")  # counts differ: maps unread
    assert r.report() == "Topologies are different: number of triangles differs (A=2,B=1)."


def test_bad_maps_and_meshes() -> None:
    with pytest.raises(TopologyMapError, match=r"face_map: expected a \(2,\) array .* found shape \(3,\)"):
        topology_equivalence(A, A, torch.arange(3), torch.arange(4))
    with pytest.raises(TopologyMapError, match=r"vertex_map: .* found values in \[0, 4\]"):
        topology_equivalence(A, A, torch.arange(2), torch.tensor([0, 1, 2, 4]))
    big = (torch.cat([V, V[:1]]), torch.tensor([[0, 1, 4], [0, 2, 3]]))  # B uses a vertex A does not have
    with pytest.raises(TopologyMapError, match="face 0 of mesh B uses vertex 4, beyond the 4 vertices of mesh A"):
        topology_equivalence(A, big, torch.arange(2), torch.arange(4))


def test_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, b = tmp_path / "a.obj", tmp_path / "b.obj"
    a.write_text(QUAD + "f 1 2 3\nf 1 3 4\n")
    b.write_text(QUAD + "f 3 4 1\nf 2 3 1\n")  # faces swapped, corners rotated
    f, v = tmp_path / "f.txt", tmp_path / "v.txt"
    f.write_text("0 1\n1 0\n")
    v.write_text("0 0\n1 1\n2 2\n3 3\n")
    args = ["mpeg", str(a), str(b), "--mode", "topo", "--face-map", str(f), "--vertex-map", str(v)]
    assert main(args) == 0
    assert capsys.readouterr().out == "Topologies are matching.\n"
    f.write_text("0 0\n1 1\n")
    assert main([*args, "--json"]) == 1
    d = json.loads(capsys.readouterr().out)
    assert (d["matching"], d["reason"], d["face_b"], d["corners_b"]) == (False, "orientation", 0, [2, 3, 0])
    f.write_text("0 0\n1 x\n")
    assert main(args) == 2  # trouble, not "not matching" (diff's convention, review S)
    assert f"{f}:2: expected two unsigned face indices" in capsys.readouterr().err
    assert main(args[:5]) == 2
    assert "--mode topo needs --face-map FILE and --vertex-map FILE" in capsys.readouterr().err
