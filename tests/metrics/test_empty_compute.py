"""Every accumulating class refuses ``compute()`` before any update with ``EmptyInputError`` (issue 23).

Before: ``MpegPSNR().compute()`` returned NaN (docs/bad-input.md promised ``EmptyInputError``). The classes are found
programmatically — every class of the package with an ``update`` and a ``compute`` (the ``torchmetrics.Metric``
subclasses, the streaming accumulators) — so a new metric without the check fails here, and one whose constructor
needs arguments must be given a factory below.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import warnings
from collections.abc import Callable
from typing import Any

import pytest

import torchmeshmetric
from torchmeshmetric._checks import EmptyInputError

# Classes whose constructor needs arguments: how to make one (with its required arguments only).
FACTORIES: dict[str, Callable[[], Any]] = {
    "SelectedStatistic": lambda: torchmeshmetric.metrics.DistanceStatisticsMetric().statistic("rmse"),
}
# A view reports its source's emptiness, named by the source.
OWNER = {"SelectedStatistic": "DistanceStatisticsMetric"}
# Classes with an update and a compute that accumulate nothing themselves (each with the reason).
NOT_ACCUMULATORS = {
    "DistanceStates": "the state names of one distance set in a metric: its compute is the metric's, tested there",
}
# Constructor keyword variants that change what is accumulated: each must refuse an empty compute too.
VARIANTS: dict[str, list[dict[str, Any]]] = {
    "DistanceStatisticsMetric": [{}, {"exact_quantiles": False}],
    "MeshSurfaceDistance": [{}, {"two_sided": True}],
    "NearestVertexDistance": [{}, {"two_sided": True}],
    "MpegPSNR": [{}, {"sampling": "mesh"}],
    "DistanceAccumulator": [{}, {"exact_quantiles": False}],
}


def _accumulating_classes() -> list[type]:
    found: dict[str, type] = {}
    for info in pkgutil.walk_packages(torchmeshmetric.__path__, "torchmeshmetric."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name, cls in vars(module).items():
            if (
                inspect.isclass(cls)
                and cls.__module__ == module.__name__
                and callable(getattr(cls, "update", None))
                and callable(getattr(cls, "compute", None))
                and not inspect.isabstract(cls)
                and name not in NOT_ACCUMULATORS
            ):
                found[f"{cls.__module__}.{name}"] = cls
    return [found[k] for k in sorted(found)]


CLASSES = _accumulating_classes()


def test_the_discovery_finds_the_known_metrics() -> None:
    names = {c.__name__ for c in CLASSES}
    assert {"MpegPSNR", "TemporalConsistency", "MeshSurfaceDistance", "DistanceAccumulator"} <= names


def _instances(cls: type) -> list[Any]:
    if cls.__name__ in FACTORIES:
        return [FACTORIES[cls.__name__]()]
    return [cls(**kwargs) for kwargs in VARIANTS.get(cls.__name__, [{}])]


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.__name__)
def test_compute_before_any_update_raises_empty_input_error(cls: type) -> None:
    for metric in _instances(cls):
        for _ in range(2):  # fresh, and again after reset()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # torchmetrics warns that compute() ran before update()
                with pytest.raises(
                    EmptyInputError,
                    match=rf"^{OWNER.get(cls.__name__, cls.__name__)}\.compute: no .* accumulated; call update",
                ):
                    metric.compute()
            if hasattr(metric, "reset"):
                metric.reset()


def test_mpeg_psnr_still_computes_after_an_update() -> None:
    import trimesh

    from torchmeshmetric.mpeg import MpegPSNR

    metric = MpegPSNR(sampling="mesh")
    sphere = trimesh.creation.icosphere(2)
    metric.update(sphere, sphere)  # identical: an infinite frame counts as accumulated
    assert metric.compute()["d1_psnr"].item() == float("inf")
    metric.reset()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # torchmetrics warns that compute() ran before update()
        with pytest.raises(EmptyInputError):
            metric.compute()
