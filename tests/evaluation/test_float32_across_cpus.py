"""The default (float32) evaluation prints the same tables on every CPU (review L, finding 2).

The evaluation's registration computed in the frames' dtype: in float32, Adam and its stopping rule amplified the
rounding of torch's per-instruction-set kernels (``at::sqrt``/``sin``/``cos``, the fused Adam's vector math), so the
``scalar`` personality of tests/cpu_personalities.py took other steps. On the demo's two frames at resolution 64
(3.2k vertices, float32, one thread), 9472 of 9480 registered coordinates differed (by up to 8.4e-4) and Table I
printed the registration's MSE as 9.0e-07 here and 8.9e-07 there, the (k-1)-th vertex set's Var as 1.8e-05 and
1.7e-05. The registration now computes in float64 (``pipeline.REGISTRATION_DTYPE``) and rounds its result to float32
once: the float64 runs agree to ~1e-11 relative (docs/statistics.md, "The same figures on every machine"), 5000 times
below float32's spacing, so a rounding can flip a coordinate by one ulp at most; measured 2026-12-07 (AMD EPYC, AVX-512,
personalities ``scalar`` and ``avx2``): 0 of 9480 coordinates differ and the tables are identical.
"""

from __future__ import annotations

import functools
import json

import pytest
import torch

from tests.cpu_personalities import OTHER_CPUS, run_as

pytestmark = pytest.mark.pinned

_RUN = """
import json, warnings
import torch
from torchmeshmetric.data import demo_sequence
from torchmeshmetric.evaluation import evaluate_sequence, paper_tables, register_pairs
from torchmeshmetric.registration import RegistrationCache

torch.set_num_threads(1)
frames = demo_sequence(2, resolution=64).frames  # float32, the same bits on every CPU (tests/data)
cache = RegistrationCache()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    result = evaluate_sequence(frames, frames, registration_cache=cache)  # lossless: only the k-th sets are 0
    (registration,) = register_pairs(frames, registration_cache=cache)  # the evaluation's, from the cache
print(json.dumps({"tables": paper_tables({"lossless": result}), "dtype": str(frames[0].dtype),
                  "registered": registration.verts.flatten().tolist()}))
"""


@functools.cache
def _run(personality: str) -> dict[str, object]:
    return dict(json.loads(run_as(OTHER_CPUS.get(personality, {}), _RUN)))


@pytest.mark.parametrize("personality", sorted(OTHER_CPUS))
def test_float32_evaluation_prints_the_same_tables_on_every_cpu(personality: str) -> None:
    here, there = _run("this CPU"), _run(personality)
    assert here["dtype"] == "torch.float32"
    assert here["tables"] == there["tables"]
    a = torch.tensor(here["registered"], dtype=torch.float32)
    b = torch.tensor(there["registered"], dtype=torch.float32)
    # At most one float32 ulp per coordinate (the float64 registrations' ~1e-11 agreement, rounded once).
    ulp = torch.nextafter(a.abs(), torch.tensor(float("inf"))) - a.abs()
    assert bool(((a - b).abs() <= ulp).all()), float(((a - b).abs() / ulp).max())
