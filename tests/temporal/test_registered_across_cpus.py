"""The registered temporal figures on every CPU: the same printed text, and the floats ~1e-13 apart.

The registered forms follow frame 0 through the evaluation's float64 registrations, whose deformation (the warp the
tracking applies) is not the same bits on every CPU: torch's and MKL's kernels round differently per instruction set
(``Tensor.norm`` and ``torch.linalg.cross`` fuse multiply-adds on AVX2/AVX-512, not on the scalar kernels; MKL's SVD
per ``MKL_CBWR`` branch). On the demo the node rotations differ by up to 1e-14 (resolution 24) and 8e-13 (80) under
the ``scalar`` personality of tests/cpu_personalities.py; the registered vertices, rounded to the float32 frames,
are the same bits, the tracked positions, in float64, differ by ~1e-15 to 1e-13. The carry step amplified that in
two places (demo, 4 frames, QEM keeping 50 %, one thread, against ``scalar``):

- a normal line grazing a face: the secant's slope ``g1 - g0`` cancelled and the step was its rounding; at
  resolution 24 one carried point moved by 8.8e-6, KG and KSO by 1.0e-5 (index sampling; 3.7e-10 canonical).
  The step now comes from the face's region (``_region_step``).
- a fin (two faces on the same three vertices, folded by the weld at resolutions 64, 80 and 120): its tip's normal is
  the rounding of two cancelling area vectors, a random direction per CPU; at resolution 64 with canonical sampling
  (the default) KG moved by 2.4e-3 and STED_s by 8.0e-3, and KG and KSO printed 0.0868 and 0.284 here, 0.0870 and
  0.285 under ``scalar``. Such a vertex now takes its closest point (``_line_normals``).

Measured after (2026-12-07, AMD EPYC, AVX-512): at most 5.7e-14 in these cases, 1.2e-12 (STED_t) over resolutions 24 to
160 and both samplings; the same bits under ``avx2``. Not bits: the library does not control the registration's
kernels, so the floats are compared to a bound (1e-11: 8x the largest measured), and the printed figures
(:func:`~torchmeshmetric.temporal.report.format_figure`) must be the same text.
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
out = {}
for resolution in (24, 64):
    frames = demo_sequence(4, resolution=resolution).frames  # float32, the same bits on every CPU (tests/data)
    simplified = [simplify_qem(m, 0.5) for m in frames]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for sampling in ("index", "canonical"):
            f = temporal_figures(frames, simplified, registration_options={"sampling": sampling})
            assert f.registered
            out[f"{resolution} {sampling}"] = {
                "floats": {name: getattr(f, name) for name in FIGURE_NAMES},
                "printed": [format_figure(name, getattr(f, name), registered=True) for name in FIGURE_NAMES],
            }
print(json.dumps(out))
"""

#: The largest relative spread a figure may show between personalities (measured: 1.2e-12 at most, module docstring).
_BOUND = 1e-11


@functools.cache
def _run(personality: str) -> dict[str, dict[str, object]]:
    return dict(json.loads(run_as(OTHER_CPUS.get(personality, {}), _RUN)))


@pytest.mark.parametrize("case", ["24 index", "24 canonical", "64 index", "64 canonical"])
@pytest.mark.parametrize("personality", sorted(OTHER_CPUS))
def test_registered_figures_agree_on_every_cpu(personality: str, case: str) -> None:
    here, there = _run("this CPU")[case], _run(personality)[case]
    assert here["printed"] == there["printed"]
    a, b = here["floats"], there["floats"]
    assert isinstance(a, dict) and isinstance(b, dict)
    spread = {name: abs(a[name] - b[name]) / max(abs(a[name]), abs(b[name])) for name in a}
    assert max(spread.values()) < _BOUND, spread
