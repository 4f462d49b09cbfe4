"""The registered temporal figures on every CPU: the same printed text, and the floats ~1e-13 apart.

The registered forms follow frame 0 through the evaluation's float64 registrations, whose deformation (the warp the
tracking applies) is not the same bits on every CPU: torch's and MKL's kernels round differently per instruction set
(``Tensor.norm`` and ``torch.linalg.cross`` fuse multiply-adds on AVX2/AVX-512, not on the scalar kernels; MKL's SVD
per ``MKL_CBWR`` branch), and the node rotations of the demo at resolution 24 differ by up to 1e-14 under the
``scalar`` personality of tests/cpu_personalities.py. The registered vertices, rounded to the float32 frames, are
the same; the tracked positions, in float64, differ by ~1e-15. The carry step amplified that: on a normal line that
grazes a face the secant's slope ``g1 - g0`` cancelled, and the step was its rounding. With index sampling (QEM
keeping 50 %, 3 frames, one thread) one carried point moved by 8.8e-6 and KG and KSO by 1.4e-5 (relative) against
``scalar``; with canonical sampling (the default) by 1.7e-11 (KG) and 2.4e-11 (STED_s). The secant now takes the
slope of the region both its points lie in (``_region_step``); measured 2027-01 (AMD EPYC, AVX-512, one thread):
at most 8.4e-14 (index) and 1.3e-14 (canonical) against ``scalar``, the same bits under ``avx2``.

Not bits: the library does not control the kernels, so the floats are compared to a bound (12x the largest
measured); the printed figures (:func:`~torchmeshmetric.temporal.report.format_figure`) must be the same text.
"""

from __future__ import annotations

import functools
import json

import pytest

from tests.cpu_personalities import OTHER_CPUS, run_as

pytestmark = pytest.mark.pinned

_RUN = """
import json, warnings
import torch
from torchmeshmetric.data import demo_sequence
from torchmeshmetric.simplification import simplify_qem
from torchmeshmetric.temporal import temporal_figures
from torchmeshmetric.temporal.figures import FIGURE_NAMES
from torchmeshmetric.temporal.report import format_figure

torch.set_num_threads(1)
frames = demo_sequence(3, resolution=24).frames  # float32, the same bits on every CPU (tests/data)
simplified = [simplify_qem(m, 0.5) for m in frames]
out = {}
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    for sampling in ("index", "canonical"):
        f = temporal_figures(frames, simplified, registration_options={"sampling": sampling})
        assert f.registered
        out[sampling] = {
            "floats": {name: getattr(f, name) for name in FIGURE_NAMES},
            "printed": [format_figure(name, getattr(f, name), registered=True) for name in FIGURE_NAMES],
        }
print(json.dumps(out))
"""

#: The largest relative spread a figure may show between personalities: 12x the largest measured (8.4e-14, KG).
_BOUND = 1e-12


@functools.cache
def _run(personality: str) -> dict[str, dict[str, object]]:
    return dict(json.loads(run_as(OTHER_CPUS.get(personality, {}), _RUN)))


@pytest.mark.parametrize("sampling", ["index", "canonical"])
@pytest.mark.parametrize("personality", sorted(OTHER_CPUS))
def test_registered_figures_agree_on_every_cpu(personality: str, sampling: str) -> None:
    here, there = _run("this CPU")[sampling], _run(personality)[sampling]
    assert here["printed"] == there["printed"]
    a, b = here["floats"], there["floats"]
    assert isinstance(a, dict) and isinstance(b, dict)
    spread = {name: abs(a[name] - b[name]) / max(abs(a[name]), abs(b[name])) for name in a}
    assert max(spread.values()) < _BOUND, spread
