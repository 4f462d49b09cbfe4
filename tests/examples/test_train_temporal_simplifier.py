"""The machinery of examples/train_temporal_simplifier.py on a tiny sequence: the loss decreases, results have shape."""

import importlib.util
import math
import sys
from pathlib import Path

import pytest
import torch

from tests.registration.expected_warnings import expects_not_converged

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


@expects_not_converged
def test_a_few_steps_decrease_the_loss_and_report_every_method(example, tmp_path):
    setup = example.Setup.quick()
    setup.steps, setup.validate_every, setup.lr, setup.anchor_weights = 3, 2, 3e-2, (0.3,)
    setup.num_train = setup.num_held_out = setup.other_frames = 3
    setup.resolution = setup.other_resolution = 20
    setup.faces = 80
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # many small ops: on a shared machine each parallel region waits for a busy core
    try:
        out = example.run(setup, str(tmp_path), registration_options={"schedule": example.quick_schedule()})
    finally:
        torch.set_num_threads(threads)
    assert out["anchor_weight"] in (0.0, *setup.anchor_weights)
    assert set(out["fit"]) == {"QEM", *(f"{w:g}" for w in setup.anchor_weights)}
    names = {"QEM", "Registered QEM", "Anchored QEM", example.MODEL, example.ACROSS}
    for name in (example.MODEL, example.ACROSS):
        curve = out["curves"][name]
        assert len(curve) == setup.steps and all(math.isfinite(x) for x in curve)
        assert curve[-1] < curve[0]  # Adam on the loss lowers it
        logged = out["validation"][name]
        assert [r["epoch"] for r in logged] == [1]  # validated every 2 epochs, through Lightning's logger
        assert {"val/flicker/ave", "val/surface_k/ave"} <= set(logged[0])
    for rep, keys in (
        (out["held_out"], ("aggregates", "true motion: aggregates")),
        (out["other_sequence"], ("aggregates",)),
    ):
        for key in keys:
            aggregates = rep[key]
            assert set(aggregates) == names
            faces = [aggregates[n]["faces"] for n in sorted(names)]
            # Equal face counts: every method simplifies to the same count (QEM to within a collapse: two faces)
            assert all(abs(f - setup.faces) <= 2 for fs in faces for f in fs), faces
            for agg in aggregates.values():
                assert all(math.isfinite(agg[k]) and agg[k] >= 0 for k in ("flicker_ave", "surface_k_ave"))
    entry = out["held_out"]["comparisons"]["Registered QEM vs Anchored QEM + slide"]["flicker"]["ave"]
    lo, hi = entry["ci95"]
    assert lo <= entry["difference"] <= hi
