import pickle

import pytest
import torch
from torchmetrics import MetricCollection

from tests.evaluation.eval_helpers import TranslationRegister
from torchmeshmetric.evaluation import SET_NAMES, TemporalConsistency, evaluate_pair, flatten_statistics
from torchmeshmetric.stats import distance_statistics


def test_metric_pools_updates_and_caches_registration(moving_spheres):
    original, simplified = moving_spheres
    register = TranslationRegister()
    metric = TemporalConsistency(register=register)
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
    metric = TemporalConsistency(two_sided=False, register=TranslationRegister())
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
    with pytest.raises(TypeError, match="register"):
        TemporalConsistency(register=3)
