"""Two configurations of one metric class never share a compute group nor merge (review H, findings 1 to 3).

torchmetrics groups the metrics of a ``MetricCollection`` whose states are equal after the first update
(``MetricCollection._equal_metric_states``) and then updates the group's first member only. State names are per class,
so two configurations of one class met there: after an empty first batch ``MeshSurfaceDistance(surface_samples=50)``
reported the exact ``MeshSurfaceDistance()``'s figures. ``merge_state`` pooled exact and sampled distances, and
``TemporalConsistency`` dropped the sets one configuration has and the other lacks.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from collections.abc import Callable
from typing import Any

import pytest
import torch
import trimesh
from torchmetrics import Metric, MetricCollection

import torchmeshmetric
from tests.evaluation.eval_helpers import TranslationRegister, sphere
from torchmeshmetric.evaluation import TemporalConsistency
from torchmeshmetric.metrics import DistanceStatisticsMetric, MeshSurfaceDistance, NearestVertexDistance
from torchmeshmetric.metrics._settings import SETTINGS_DIGEST, SettingsMetric
from torchmeshmetric.mpeg import MpegPSNR
from torchmeshmetric.registration import NonRigidOptions


def _mesh(num_verts: int, num_faces: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    verts = torch.rand(num_verts, 3, generator=g, dtype=torch.float64)
    return verts, torch.randint(0, num_verts, (num_faces, 3), generator=g)


REFERENCE, SIMPLIFIED = _mesh(15, 20, 1), _mesh(10, 8, 2)


def _refused(into: Metric, incoming: dict[str, Any] | Metric) -> str:
    before = {k: v.clone() if isinstance(v, torch.Tensor) else list(v) for k, v in into.metric_state.items()}
    with pytest.raises(ValueError, match=r"^incoming_state: ") as raised:
        into.merge_state(incoming)
    for key, value in into.metric_state.items():  # refused before anything merged
        assert torch.equal(value, before[key]) if isinstance(value, torch.Tensor) else value == before[key], key
    return str(raised.value)


def test_merge_state_refuses_sampled_into_exact():
    # Accepted before: exact and sampled (over-estimated) distances pooled into one set of 20.
    exact = MeshSurfaceDistance()
    exact.update(SIMPLIFIED, REFERENCE)
    sampled = MeshSurfaceDistance(surface_samples=20)
    sampled.update(_mesh(10, 8, 3), REFERENCE)
    assert _refused(exact, sampled) == (
        "incoming_state: MeshSurfaceDistance(two_sided=False, exact_quantiles=True, surface_samples=20, seed=0) "
        "cannot merge into MeshSurfaceDistance(two_sided=False, exact_quantiles=True, surface_samples=None): their "
        "states hold different measurements; merge metrics built with the same options"
    )
    assert "surface_samples=None) cannot merge" in _refused(sampled, exact)
    assert "seed=1) cannot merge" in _refused(sampled, MeshSurfaceDistance(surface_samples=20, seed=1))
    same = MeshSurfaceDistance(surface_samples=20)
    same.update(SIMPLIFIED, REFERENCE)
    both = MeshSurfaceDistance(surface_samples=20)
    both.update(_mesh(10, 8, 3), REFERENCE)
    both.update(SIMPLIFIED, REFERENCE)
    sampled.merge_state(same)
    merged, expected = sampled.compute(), both.compute()
    assert merged["count"].item() == 20.0
    for key in ("ave", "max", "median", "var"):
        assert merged[key].item() == pytest.approx(expected[key].item(), rel=1e-12), key
    exact_seeds = MeshSurfaceDistance(seed=5)  # the exact distances read no seed: the same measurement
    exact_seeds.update(SIMPLIFIED, REFERENCE)
    exact.merge_state(exact_seeds)
    assert exact.compute()["count"].item() == 20.0


def test_merge_state_refuses_other_mpeg_sampling():
    sphere = trimesh.creation.icosphere(2)
    grid, mesh = MpegPSNR(grid_size=64), MpegPSNR(sampling="mesh")
    grid.update(sphere.copy().apply_scale(1.01), sphere)
    mesh.update(sphere.copy().apply_scale(1.02), sphere)
    assert _refused(grid, mesh).startswith(
        "incoming_state: MpegPSNR(sampling='mesh') cannot merge into MpegPSNR(sampling='grid', grid_size=64): "
    )
    assert "grid_size=64) cannot merge into MpegPSNR(sampling='grid', grid_size=128)" in _refused(
        MpegPSNR(grid_size=128), grid
    )


def _temporal(**kwargs: Any) -> TemporalConsistency:
    """A metric of one update on translated spheres (frames 0 and 1), with ``kwargs``."""
    metric = TemporalConsistency(registration_fn=TranslationRegister(), **kwargs)
    original = [sphere(2, offset=(0.1 * k, 0, 0)) for k in range(2)]
    simplified = [sphere(1, offset=(0.1 * k, 0, 0)) for k in range(2)]
    flicker = {"simplified_k_minus_1": simplified[0]} if kwargs.get("flicker") else {}
    metric.update(simplified[1], original[1], original[0], **flicker)
    return metric


def _shown(**kwargs: Any) -> str:
    sets = {"two_sided": True, "flicker": False, **kwargs}
    return (
        f"TemporalConsistency(two_sided={sets['two_sided']}, flicker={sets['flicker']}, "
        "registration_fn='cache_key:tests.TranslationRegister(step=0.1)', registration_options={})"
    )


@pytest.mark.parametrize(
    ("into", "incoming", "found"),
    [
        ({"two_sided": False}, {}, "unknown 8 (reverse_surface_k_minus_1_moments, "),  # dropped in silence
        ({}, {"two_sided": False}, "missing 8 (reverse_surface_k_minus_1_moments, "),  # 9.7 kB of tensors
        ({}, {"flicker": True}, "unknown 4 (flicker_moments, flicker_values, "),  # dropped in silence
        ({"flicker": True}, {}, "missing 4 (flicker_moments, flicker_values, "),  # 9.7 kB of tensors
    ],
)
def test_temporal_consistency_refuses_other_sets_both_ways(into, incoming, found):
    target, other = _temporal(**into), _temporal(**incoming)
    message = _refused(target, other)
    assert message == (
        f"incoming_state: {_shown(**incoming)} cannot merge into {_shown(**into)}: their states hold different "
        "measurements; merge metrics built with the same options"
    )
    # As a dict: named by the states it lacks or has too many of, in a line (no tensor printed).
    message = _refused(target, other.metric_state)
    assert message.startswith(f"incoming_state: expected the states of {_shown(**into)}, found {found}")
    assert len(message) < 400
    same = _temporal(**into)
    target.merge_state(same)  # the same sets still merge: every set holds both updates' distances
    alone = _temporal(**into).compute()
    assert target.compute()["vertex_k"]["count"].item() == 2 * alone["vertex_k"]["count"].item()
    assert target.compute()["vertex_k"]["ave"].item() == pytest.approx(alone["vertex_k"]["ave"].item(), rel=1e-12)


def test_temporal_consistency_refuses_other_registrations():
    default = TemporalConsistency()
    quick = TemporalConsistency(registration_options={"num_points": 500})
    assert (
        "registration_options={'num_points': 500}) cannot merge into TemporalConsistency(two_sided=True, "
        "flicker=False, registration_fn=None, registration_options={})" in _refused(default, quick)
    )
    assert "registration_fn=None" in _refused(_temporal(), default)


# Pairs of configurations whose states hold different measurements, for every metric class with such options.
DIFFERENT: list[tuple[Callable[[], Metric], Callable[[], Metric]]] = [
    (MeshSurfaceDistance, lambda: MeshSurfaceDistance(surface_samples=50)),
    (lambda: MeshSurfaceDistance(surface_samples=50), lambda: MeshSurfaceDistance(surface_samples=50, seed=1)),
    (lambda: MeshSurfaceDistance(surface_samples=50), lambda: MeshSurfaceDistance(surface_samples=60)),
    (
        lambda: DistanceStatisticsMetric(exact_quantiles=False, relative_accuracy=0.01),
        lambda: DistanceStatisticsMetric(exact_quantiles=False, relative_accuracy=0.0100001),  # as many bins
    ),
    (MpegPSNR, lambda: MpegPSNR(sampling="mesh")),
    (lambda: MpegPSNR(grid_size=64), lambda: MpegPSNR(grid_size=128)),
    (TemporalConsistency, lambda: TemporalConsistency(registration_options={"num_points": 500})),
    (lambda: TemporalConsistency(registration_fn=TranslationRegister()), TemporalConsistency),
]
# Pairs that differ only in what compute() reads (ddof, peak) or in rounding (backend): one group is right for them.
SAME: list[tuple[Callable[[], Metric], Callable[[], Metric]]] = [
    (MeshSurfaceDistance, lambda: MeshSurfaceDistance(ddof=1, peak=2.0, backend="bruteforce", seed=3)),  # seed: unread
    (NearestVertexDistance, lambda: NearestVertexDistance(backend="bruteforce")),
    (lambda: MpegPSNR(sampling="mesh", grid_size=64), lambda: MpegPSNR(sampling="mesh")),  # grid_size: unread
    (
        lambda: TemporalConsistency(registration_options={"num_points": 500}),
        lambda: TemporalConsistency(registration_options=NonRigidOptions(num_points=500)),  # the same, spelled apart
    ),
    (
        lambda: TemporalConsistency(registration_fn=TranslationRegister()),
        lambda: TemporalConsistency(registration_fn=TranslationRegister()),
    ),
]


@pytest.mark.parametrize(("make_a", "make_b"), DIFFERENT)
def test_two_configurations_never_hold_equal_states(make_a, make_b):
    # The check torchmetrics groups metrics by, on the states both hold before any update (what an empty first batch
    # leaves): equal before, for every pair.
    a, b = make_a(), make_b()
    assert a._settings() != b._settings()
    assert not MetricCollection._equal_metric_states(a, b)


@pytest.mark.parametrize(("make_a", "make_b"), SAME)
def test_one_configuration_still_shares_a_group(make_a, make_b):
    a, b = make_a(), make_b()
    assert a._settings() == b._settings()
    assert MetricCollection._equal_metric_states(a, b)


def test_an_empty_first_batch_keeps_exact_and_sampled_apart():
    # The review's reproduction: the sampled metric reported the exact one's ave, 0.20474041212216906.
    collection = MetricCollection({"exact": MeshSurfaceDistance(), "sampled": MeshSurfaceDistance(surface_samples=50)})
    collection.update(torch.zeros(0, 3, dtype=torch.float64), REFERENCE)
    assert collection.compute_groups == {0: ["exact"], 1: ["sampled"]}
    collection.update(SIMPLIFIED, REFERENCE)
    out = collection.compute()
    alone = {"exact": MeshSurfaceDistance(), "sampled": MeshSurfaceDistance(surface_samples=50)}
    for name, metric in alone.items():
        metric.update(SIMPLIFIED, REFERENCE)
        for key, value in metric.compute().items():
            assert torch.equal(out[f"{name}_{key}"], value), (name, key)
    assert out["exact_ave"].item() == pytest.approx(0.20474041212216906, rel=1e-12)
    assert out["sampled_ave"].item() == pytest.approx(0.26136866976167084, rel=1e-12)


def test_an_identical_first_frame_keeps_two_mpeg_grids_apart():
    # An identical first pair is an infinite frame in both: equal states (sum 0, one inf frame), then one group.
    sphere = trimesh.creation.icosphere(2)
    scaled = sphere.copy().apply_scale(1.01)
    collection = MetricCollection({"coarse": MpegPSNR(grid_size=64), "fine": MpegPSNR(grid_size=128)})
    collection.update(sphere, sphere)
    assert collection.compute_groups == {0: ["coarse"], 1: ["fine"]}
    collection.update(scaled, sphere)
    out = collection.compute()
    for name, grid_size in (("coarse", 64), ("fine", 128)):
        alone = MpegPSNR(grid_size=grid_size)
        alone.update(sphere, sphere)
        alone.update(scaled, sphere)
        for key, value in alone.compute().items():
            assert torch.equal(out[f"{name}_{key}"], value), (name, key)
    assert out["coarse_d1_psnr"].item() != out["fine_d1_psnr"].item()
    assert out["coarse_d1_psnr_inf_frames"].item() == 1.0


def test_checkpoints_keep_their_keys():
    # The digest is the constructor's: never in a state_dict. The states come with the settings they were accumulated
    # with (review Q: a metric of other settings loaded them in silence), which a metric of those settings loads.
    sampled = MeshSurfaceDistance(surface_samples=50)
    sampled.persistent(True)
    sampled.update(SIMPLIFIED, REFERENCE)
    state = sampled.state_dict()
    assert sorted(state) == ["reference_peak", "states_settings", "surface_moments", "surface_values"]
    loaded = MeshSurfaceDistance(surface_samples=50)
    loaded.persistent(True)
    loaded.load_state_dict(state)
    loaded._update_count = 1  # a loaded state counts no update
    assert loaded.compute()["ave"].item() == sampled.compute()["ave"].item()
    assert getattr(loaded, SETTINGS_DIGEST).tolist() == getattr(sampled, SETTINGS_DIGEST).tolist()


def test_a_metric_pickled_before_the_digest_gets_it_when_unpickled():
    sampled = MeshSurfaceDistance(surface_samples=50)
    state = sampled.__getstate__()
    for table in ("_defaults", "_persistent", "_reductions"):
        state[table] = {k: v for k, v in state[table].items() if k != SETTINGS_DIGEST}
    del state[SETTINGS_DIGEST]
    old = MeshSurfaceDistance.__new__(MeshSurfaceDistance)
    old.__setstate__(state)
    assert getattr(old, SETTINGS_DIGEST).tolist() == getattr(sampled, SETTINGS_DIGEST).tolist()
    assert not MetricCollection._equal_metric_states(old, MeshSurfaceDistance())


def _metric_classes() -> list[type]:
    found: dict[str, type] = {}
    for info in pkgutil.walk_packages(torchmeshmetric.__path__, "torchmeshmetric."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for cls in vars(module).values():
            if inspect.isclass(cls) and issubclass(cls, Metric) and cls.__module__ == module.__name__:
                found[f"{cls.__module__}.{cls.__name__}"] = cls
    return [found[k] for k in sorted(found)]


# Metric classes that hold no state of their own (torchmetrics never groups a metric without states).
STATELESS = {"SelectedStatistic"}


def test_every_metric_class_has_settings():
    # Found by walking the package, so that a new metric class without settings fails here.
    classes = _metric_classes()
    assert {"MeshSurfaceDistance", "TemporalConsistency", "MpegPSNR"} <= {c.__name__ for c in classes}
    for cls in classes:
        assert cls.__name__ in STATELESS or issubclass(cls, SettingsMetric), cls


@pytest.mark.filterwarnings(
    "ignore:The ``compute`` method of metric MeshSurfaceDistance was called before:UserWarning"
)  # a merged state counts no update
def test_merge_state_refuses_a_state_dict_of_other_settings():
    # A dict carries the settings' digest: the sampled metric's states were taken by the exact one.
    exact, sampled = MeshSurfaceDistance(), MeshSurfaceDistance(surface_samples=20)
    sampled.update(SIMPLIFIED, REFERENCE)
    message = _refused(exact, sampled.metric_state)
    assert message == (
        "incoming_state: the states of a metric built with other options cannot merge into MeshSurfaceDistance("
        "two_sided=False, exact_quantiles=True, surface_samples=None) (its settings_digest differs)"
    )
    undigested = {k: v for k, v in sampled.metric_state.items() if k != SETTINGS_DIGEST}  # a dict written before
    fresh = MeshSurfaceDistance(surface_samples=20)
    fresh.merge_state(undigested)
    assert fresh.compute()["ave"].item() == sampled.compute()["ave"].item()


def test_load_state_dict_refuses_the_states_of_other_settings():
    # Review Q: load_state_dict took a sampled metric's states into the exact metric in silence, and the next update
    # pooled sampled and exact distances (merge_state refuses them).
    import torch.nn as nn

    from torchmeshmetric.metrics._settings import SETTINGS_KEY

    simplified, reference = trimesh.creation.icosphere(subdivisions=1), trimesh.creation.icosphere(subdivisions=3)
    sampled = MeshSurfaceDistance(surface_samples=20)
    sampled.persistent(True)
    sampled.update(simplified, reference)
    written = sampled.state_dict()
    assert bytes(written[SETTINGS_KEY].tolist()).decode() == sampled._settings()
    exact = MeshSurfaceDistance()
    with pytest.raises(ValueError, match=r"^state_dict: the states of MeshSurfaceDistance\(.*surface_samples=20, "):
        exact.load_state_dict(written)
    assert exact._update_count == 0 and not exact.surface_values  # nothing loaded
    same = MeshSurfaceDistance(surface_samples=20)  # the same settings load, strictly, in a module too
    same.load_state_dict(written)
    same._update_count = 1  # a loaded state counts no update
    assert float(same.compute()["ave"]) == float(sampled.compute()["ave"])
    holder, other = nn.ModuleDict({"m": MeshSurfaceDistance(surface_samples=20)}), nn.ModuleDict({"m": exact})
    holder["m"].persistent(True)
    holder["m"].update(simplified, reference)
    with pytest.raises(ValueError, match="cannot load into"):
        other.load_state_dict(holder.state_dict())
    nn.ModuleDict({"m": MeshSurfaceDistance(surface_samples=20)}).load_state_dict(holder.state_dict(), strict=True)
    # Written before the key existed (or without states): loads as it did; torchmetrics' default writes no key.
    old = {k: v for k, v in written.items() if k != SETTINGS_KEY}
    MeshSurfaceDistance().load_state_dict(old)
    assert MeshSurfaceDistance(surface_samples=20).state_dict() == {}
