import pickle

import pytest
import torch
from torchmetrics import MetricCollection

from tests.evaluation.eval_helpers import TranslationRegister
from torchmeshmetric import EmptyInputError
from torchmeshmetric.evaluation import FLICKER, SET_NAMES, TemporalConsistency, evaluate_pair, flatten_statistics
from torchmeshmetric.evaluation.temporal_consistency import _FORWARD_STATES, _REVERSE_STATES
from torchmeshmetric.stats import distance_statistics


def test_metric_pools_updates_and_caches_registration(moving_spheres):
    original, simplified = moving_spheres
    register = TranslationRegister()
    metric = TemporalConsistency(registration_fn=register)
    pairs = []
    for _epoch in range(2):
        metric.reset()
        for k in range(1, 4):
            metric.update(simplified[k], original[k], original[k - 1])
            pairs.append(
                evaluate_pair(simplified[k], original[k], original[k - 1], registration_fn=TranslationRegister())
            )
    assert register.calls == 3  # second epoch: all registrations from the in-memory cache
    out = metric.compute()
    peak = max(p.peak for p in pairs[-3:])
    for name in SET_NAMES:
        pooled = torch.cat([p.distances[name] for p in pairs[-3:]])
        expect = distance_statistics(pooled, peak=peak).as_dict()
        for field, value in expect.items():
            assert float(out[name][field]) == pytest.approx(value, rel=1e-12, abs=1e-15)
        pooled_rev = torch.cat([p.reverse_distances[name] for p in pairs[-3:]])
        assert float(out["reverse"][name]["rmse"]) == pytest.approx(
            float(distance_statistics(pooled_rev).rmse), rel=1e-12
        )


def test_metric_one_sided_collection_and_pickle(moving_spheres):
    original, simplified = moving_spheres
    metric = TemporalConsistency(two_sided=False, registration_fn=TranslationRegister())
    coll = MetricCollection({"tc": metric})
    coll.update(simplified[1], original[1], original[0])
    out = coll.compute()  # a collection merges a metric's dict output into its own dict
    assert set(out) == set(SET_NAMES)
    flat = flatten_statistics(out)
    assert "surface_k_minus_1/rmse" in flat
    clone = pickle.loads(pickle.dumps(metric))
    assert float(clone.compute()["vertex_k"]["ave"]) == float(metric.compute()["vertex_k"]["ave"])


def test_metric_rejects_bad_arguments():
    with pytest.raises(TypeError, match="two_sided"):
        TemporalConsistency(two_sided="yes")
    with pytest.raises(TypeError, match="registration_fn"):
        TemporalConsistency(registration_fn=3)


def test_states_declared_for_every_set_and_merged_like_a_ddp_gather(moving_spheres):
    original, simplified = moving_spheres
    assert set(_FORWARD_STATES) == set(_REVERSE_STATES) == {*SET_NAMES, FLICKER}
    whole, part_a, part_b = (TemporalConsistency(registration_fn=TranslationRegister()) for _ in range(3))
    for k in range(1, 4):
        whole.update(simplified[k], original[k], original[k - 1])
        (part_a if k < 3 else part_b).update(simplified[k], original[k], original[k - 1])
    part_a.merge_state(part_b)  # the reductions a DDP sync applies: moments rows and values concatenated
    expected, merged = whole.compute(), part_a.compute()
    for name in SET_NAMES:
        for field, value in expected[name].items():
            assert float(merged[name][field]) == pytest.approx(float(value), rel=1e-12, abs=1e-15), (name, field)


@pytest.mark.filterwarnings("ignore:The ``compute`` method of metric TemporalConsistency was called before:UserWarning")
def test_empty_compute_raises():
    with pytest.raises(EmptyInputError, match="no surface_k_minus_1 distances"):
        TemporalConsistency(registration_fn=TranslationRegister()).compute()


@pytest.mark.parametrize("position", ["simplified_k", "original_k", "original_k_minus_1", "simplified_k_minus_1"])
def test_update_names_the_argument_that_is_not_a_mesh(moving_spheres, position):
    # Found by review: update(None, s, s) said "mesh: expected a Mesh ...", naming none of the three.
    original, simplified = moving_spheres
    args = {
        "simplified_k": simplified[1],
        "original_k": original[1],
        "original_k_minus_1": original[0],
        "simplified_k_minus_1": simplified[0],
    }
    args[position] = None if position != "simplified_k_minus_1" else "frame.obj?"
    metric = TemporalConsistency(registration_fn=TranslationRegister(), flicker=True)
    with pytest.raises(TypeError, match=rf"^{position}: "):
        metric.update(**args)
