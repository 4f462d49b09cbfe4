"""Registered QEM (ours, numpy) vs fast-simplification (C++) on a ~40k-face demo frame.

Run: ``python -m pytest tests/benchmarks/test_simplification_bench.py --benchmark-only``. Goal (issue 4): ours
<= 2 s for 50 % and for 97 % face reduction on 2 CPU cores; the ratio to fast-simplification is reported in
docs/simplification.md.
"""

import pytest

from torchmeshmetric import Mesh
from torchmeshmetric.data import demo_sequence
from torchmeshmetric.simplification import simplify_qem, simplify_registered_qem


@pytest.fixture(scope="module")
def frames():
    seq = demo_sequence(2)  # ~20k vertices / ~40k faces per frame
    prev = seq.frames[0]
    registered = Mesh(seq.transfer(prev.verts.double(), 0, 1).float(), prev.faces)
    return seq.frames[1], registered


@pytest.mark.parametrize("keep", [0.5, 0.03], ids=["reduce50", "reduce97"])
@pytest.mark.parametrize("method", ["registered_qem", "registered_qem_w0", "fast_simplification"])
def test_simplify(benchmark, frames, method, keep):
    mesh, registered = frames
    benchmark.group = f"simplify-{keep}"
    if method == "fast_simplification":
        out = benchmark.pedantic(simplify_qem, args=(mesh, keep), rounds=5, iterations=1)
    else:
        w = 1.0 if method == "registered_qem" else 0.0
        out = benchmark.pedantic(
            simplify_registered_qem, args=(mesh, registered, keep), kwargs={"weight": w}, rounds=3, iterations=1
        )
    assert abs(out.num_faces - round(keep * mesh.num_faces)) <= 2
