"""NonRigidOptions: validation, canonical form, the keyword spelling of register_nonrigid, the cache key."""

from __future__ import annotations

import copy
import dataclasses
import inspect
import json
import math
import pickle

import pytest
import torch
import trimesh

from tests.registration.expected_warnings import expects_not_converged
from torchmeshmetric import Mesh
from torchmeshmetric.registration import DEFAULT_SCHEDULE, NonRigidOptions, Stage, register_nonrigid, registration_key
from torchmeshmetric.registration.options import RUN_ARGUMENTS

SHORT = (DEFAULT_SCHEDULE[0]._replace(max_steps=8), DEFAULT_SCHEDULE[1]._replace(max_steps=4))


def _stage(**changes):
    return DEFAULT_SCHEDULE[0]._replace(**changes)


def test_defaults_are_the_documented_ones():
    o = NonRigidOptions()
    assert o.schedule == DEFAULT_SCHEDULE and o.num_points == 2000 and o.rigid_init is True
    assert o.rigid_options is not None and o.rigid_options["point_to_plane"] is True
    assert o.rigid_options["max_iterations"] == 30  # register_rigid's own default, filled in
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.num_points = 3  # type: ignore[misc]
    with pytest.raises(TypeError):
        o.rigid_options["trim"] = 0.5  # type: ignore[index]  # read-only, like the rest


def test_equal_settings_spelled_differently_are_one_option_and_one_key():
    m = Mesh(torch.eye(3, dtype=torch.float64), torch.tensor([[0, 1, 2]]))
    spellings = [
        NonRigidOptions(node_spacing=0.05, schedule=SHORT),
        NonRigidOptions(node_spacing=0.05, schedule=list(SHORT), rigid_options={"point_to_plane": True}),
        NonRigidOptions(
            node_spacing=0.05,
            schedule=[s._replace(max_normal_angle=int(s.max_normal_angle)) for s in SHORT],  # 80 and 80.0
            rigid_options={"max_iterations": 30, "trim": 0.9},  # register_rigid's defaults written out
            num_points=2000,
        ),
        NonRigidOptions.from_keywords(NonRigidOptions(schedule=SHORT), node_spacing=0.05),
        NonRigidOptions.from_call({"options": NonRigidOptions(schedule=SHORT), "node_spacing": 0.05, "warn": False}),
    ]
    keys = {registration_key(m, m, o) for o in spellings}
    assert len(keys) == 1
    assert all(o == spellings[0] and hash(o) == hash(spellings[0]) for o in spellings)
    # The key of settings holding the options follows the options too.
    assert len({registration_key(m, m, {"register": "r", "options": o}) for o in spellings}) == 1


def test_different_settings_never_share_a_key():
    m = Mesh(torch.eye(3, dtype=torch.float64), torch.tensor([[0, 1, 2]]))
    variants = [
        NonRigidOptions(),
        NonRigidOptions(rigid_init=False),
        NonRigidOptions(node_spacing=0.031),
        NonRigidOptions(num_neighbors=5),
        NonRigidOptions(num_points=1999),
        NonRigidOptions(num_target_samples=0),
        NonRigidOptions(correspondence_every=9),
        NonRigidOptions(schedule=DEFAULT_SCHEDULE[:3]),
        NonRigidOptions(plane_weight=0.9),
        NonRigidOptions(point_weight=0.2),
        NonRigidOptions(reverse_weight=0.0),
        NonRigidOptions(tolerance=1e-4),
        NonRigidOptions(adam_eps=1e-5),
        NonRigidOptions(max_outlier_fraction=0.2),
        NonRigidOptions(outlier_distance=0.03),
        NonRigidOptions(max_uncovered_fraction=0.01),
        NonRigidOptions(outlier_edge_factor=3.0),
        NonRigidOptions(node_edge_factor=1.0),
        NonRigidOptions(sampling="canonical"),
        NonRigidOptions(rigid_options={"point_to_plane": False}),
        NonRigidOptions(rigid_options={"init": torch.eye(4)}),
        NonRigidOptions(rigid_options={"init": 2 * torch.eye(4)}),
    ]
    # Every field of every stage, one at a time.
    for field in Stage._fields:
        value = getattr(DEFAULT_SCHEDULE[2], field)
        changed = DEFAULT_SCHEDULE[2]._replace(**{field: value * 0.5 if field == "lr_decay" else value + 1})
        variants.append(NonRigidOptions(schedule=(*DEFAULT_SCHEDULE[:2], changed, DEFAULT_SCHEDULE[3])))
    default = NonRigidOptions().canonical()
    assert {f.name for f in dataclasses.fields(NonRigidOptions)} <= {
        name for v in variants[1:21] for name, x in v.canonical().items() if x != default.get(name)
    }  # every field is varied above
    keys = [registration_key(m, m, o) for o in variants]
    assert len(set(keys)) == len(keys)
    assert len({o for o in variants}) == len(variants)
    # Options are never mistaken for plain settings that print alike.
    assert registration_key(m, m, NonRigidOptions()) != registration_key(m, m, NonRigidOptions().canonical())


def test_options_pickle_and_copy():
    o = NonRigidOptions(num_points=77, schedule=SHORT, rigid_options={"init": torch.eye(4), "trim": 0.8})
    for back in (pickle.loads(pickle.dumps(o)), copy.deepcopy(o), copy.copy(o), dataclasses.replace(o)):
        assert back == o and back.num_points == 77 and back.schedule == SHORT
        assert torch.equal(back.rigid_options["init"], torch.eye(4))


def test_canonical_form_is_json_and_exact():
    o = NonRigidOptions(tolerance=0.1 + 0.2, rigid_options={"init": torch.eye(4, dtype=torch.float32)})
    back = json.loads(json.dumps(o.canonical()))
    assert back["tolerance"] == 0.1 + 0.2  # the float's every bit survives
    assert back["schedule"][0] == DEFAULT_SCHEDULE[0]._asdict()
    assert back["rigid_options"]["init"]["values"][0] == 1.0
    # Every field but the default sampling, left out so that the keys cached before the option stay the same.
    assert set(back) == {f.name for f in dataclasses.fields(NonRigidOptions)} - {"sampling"}
    assert set(NonRigidOptions(sampling="dense").canonical()) == {f.name for f in dataclasses.fields(NonRigidOptions)}


@pytest.mark.parametrize(
    ("changes", "error", "match"),
    [
        ({"num_points": 2.5}, TypeError, r"^num_points: expected an int, found float 2\.5"),
        ({"num_points": 0}, ValueError, r"^num_points: expected an int >= 1, found 0"),
        ({"num_target_samples": -1}, ValueError, r"^num_target_samples: expected an int >= 0"),
        ({"correspondence_every": True}, TypeError, r"^correspondence_every: expected an int, found bool"),
        ({"rigid_init": 1}, TypeError, r"^rigid_init: expected a bool, found int"),
        ({"node_spacing": 0.0}, ValueError, r"^node_spacing: expected a float in \(0, inf\], found 0\.0"),
        ({"node_spacing": math.inf}, ValueError, r"^node_spacing: expected a finite float"),
        ({"plane_weight": math.nan}, ValueError, r"^plane_weight: expected a float in \[0, inf\], found nan"),
        ({"point_weight": "0.1"}, TypeError, r"^point_weight: expected a float, found str"),
        ({"max_outlier_fraction": 1.5}, ValueError, r"^max_outlier_fraction: expected a float in \[0, 1\]"),
        ({"max_uncovered_fraction": -0.1}, ValueError, r"^max_uncovered_fraction: expected a float in \[0, 1\]"),
        ({"outlier_edge_factor": math.inf}, ValueError, r"^outlier_edge_factor: expected a finite float"),
        ({"outlier_edge_factor": -1.0}, ValueError, r"^outlier_edge_factor: expected a float in \[0, inf\]"),
        ({"node_edge_factor": math.nan}, ValueError, r"^node_edge_factor: expected a float in \[0, inf\], found nan"),
        ({"node_edge_factor": "1"}, TypeError, r"^node_edge_factor: expected a float, found str"),
        ({"schedule": []}, ValueError, r"^schedule: expected at least one stage, found none"),
        ({"schedule": "stages"}, TypeError, r"^schedule: expected a sequence of Stage"),
        ({"schedule": [tuple(DEFAULT_SCHEDULE[0])]}, TypeError, r"^schedule\[0\]: expected a Stage, found tuple"),
        ({"schedule": [DEFAULT_SCHEDULE[0], _stage(lr=0.0)]}, ValueError, r"^schedule\[1\]\.lr: expected a float"),
        ({"schedule": [_stage(max_steps=-1)]}, ValueError, r"^schedule\[0\]\.max_steps: expected an int >= 0"),
        ({"schedule": [_stage(max_normal_angle=190.0)]}, ValueError, r"^schedule\[0\]\.max_normal_angle:"),
        ({"schedule": [_stage(robust_scale=0.0)]}, ValueError, r"^schedule\[0\]\.robust_scale:"),
        # its square underflowed to 0: the Geman-McClure kernel was 0 / 0 at a zero residual, a NaN loss
        (
            {"schedule": [_stage(robust_scale=1e-300)]},
            ValueError,
            r"^schedule\[0\]\.robust_scale: expected a float in \[1e-12",
        ),
        # inf passed and made the acceptance weight's smoothstep NaN: the loss was NaN at the first step (review I #8)
        ({"schedule": [_stage(max_distance=math.inf)]}, ValueError, r"^schedule\[0\]\.max_distance: expected a finite"),
        # no data could move the graph: the rigid start came back reported converged (review I #9)
        (
            {"schedule": [_stage(max_steps=0), DEFAULT_SCHEDULE[1]._replace(max_steps=0)]},
            ValueError,
            r"^schedule: expected a stage with max_steps > 0, found only stages of 0 steps",
        ),
        (
            {"plane_weight": 0.0, "point_weight": 0},
            ValueError,
            r"^plane_weight, point_weight: expected at least one > 0, found both 0",
        ),
        ({"rigid_options": {"generator": None}}, TypeError, r"^rigid_options: expected keywords of register_rigid"),
        ({"rigid_options": [("trim", 0.5)]}, TypeError, r"^rigid_options: expected a mapping"),
    ],
)
def test_bad_options_raise_typed_errors_naming_the_field(changes, error, match):
    with pytest.raises(error, match=match):
        NonRigidOptions(**changes)


def test_unknown_keyword_is_named():
    with pytest.raises(TypeError, match=r"^num_point: not a registration option"):
        NonRigidOptions.from_keywords(num_point=3)
    with pytest.raises(TypeError, match="num_point"):
        register_nonrigid(trimesh.creation.box(), trimesh.creation.box(), num_point=3)
    with pytest.raises(TypeError, match="options: expected NonRigidOptions"):
        register_nonrigid(trimesh.creation.box(), trimesh.creation.box(), {"num_points": 3})  # type: ignore[arg-type]


def test_run_arguments_are_the_keywords_of_register_nonrigid():
    params = inspect.signature(register_nonrigid).parameters.values()
    assert {p.name for p in params if p.kind is p.KEYWORD_ONLY} == RUN_ARGUMENTS
    assert not RUN_ARGUMENTS & {f.name for f in dataclasses.fields(NonRigidOptions)}


@expects_not_converged
def test_options_and_keywords_give_the_same_registration():
    src = trimesh.creation.icosphere(subdivisions=2)
    tgt = trimesh.creation.icosphere(subdivisions=2)
    tgt.vertices *= [1.1, 1.0, 0.9]
    kw = {"schedule": SHORT, "num_points": 300, "num_target_samples": 300, "correspondence_every": 4}
    by_keywords = register_nonrigid(src, tgt, **kw)
    by_options = register_nonrigid(src, tgt, NonRigidOptions(**kw))
    mixed = register_nonrigid(src, tgt, NonRigidOptions(num_points=7, schedule=SHORT), num_points=300,
                              num_target_samples=300, correspondence_every=4)  # fmt: skip
    for r in (by_options, mixed):
        assert torch.equal(r.verts, by_keywords.verts) and r.loss_history == by_keywords.loss_history
    # SHORT is a 12-step schedule cut short: not converged by the stated criterion, and said so alike by all three.
    assert not by_keywords.converged and "not converged" in by_keywords.reason
    assert by_options.reason == mixed.reason == by_keywords.reason
