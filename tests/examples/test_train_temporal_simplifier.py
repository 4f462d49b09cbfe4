"""The machinery of examples/train_temporal_simplifier.py on a tiny sequence: the loss decreases, results have shape."""

import importlib.util
import math
import sys
from pathlib import Path

import pytest

pytest.importorskip("lightning")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "train_temporal_simplifier.py"


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("train_temporal_simplifier", EXAMPLE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses resolve their annotations through sys.modules
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        del sys.modules[spec.name]


def test_a_few_steps_decrease_the_loss_and_report_every_method(example, tmp_path):
    setup = example.Setup(num_train=3, num_held_out=3, resolution=24, faces=120, steps=4, validate_every=2, lr=3e-2)
    out = example.run(setup, (1.0,), str(tmp_path), registration_options={"schedule": example.quick_schedule()})
    curve = out["curves"]["MLP λ=1"]
    assert len(curve) == setup.steps and all(math.isfinite(x) for x in curve)
    assert curve[-1] < curve[0]  # the model starts as QEM; Adam on the loss lowers it
    logged = out["validation"]["MLP λ=1"]
    assert [r["epoch"] for r in logged] == [1, 3]  # validated every 2 epochs, through Lightning's logger
    assert {"val/flicker/ave", "val/surface_k/ave"} <= set(logged[0])
    aggregates = out["aggregates"]
    assert set(aggregates) == {"QEM", "Registered QEM", "MLP λ=1"}
    # Equal face counts: the model keeps QEM's faces
    assert aggregates["MLP λ=1"]["faces"] == aggregates["QEM"]["faces"]
    for agg in aggregates.values():
        assert all(math.isfinite(agg[k]) and agg[k] >= 0 for k in ("flicker_ave", "surface_k_ave"))
    entry = out["comparisons"]["QEM vs MLP λ=1"]["flicker"]["ave"]
    lo, hi = entry["ci95"]
    assert lo <= entry["difference"] <= hi
