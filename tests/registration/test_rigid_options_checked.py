"""NonRigidOptions validates its rigid_options when built, with register_rigid's own checks (issue 41, theme 8)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from torchmeshmetric.registration import NonRigidOptions, register_rigid


@pytest.mark.parametrize(
    ("options", "error", "message"),
    [
        ({"max_iterations": -3}, ValueError, "rigid_options: max_iterations: expected an int >= 0, found -3"),
        ({"max_iterations": "ten"}, TypeError, "rigid_options: max_iterations: expected an int, found str 'ten'"),
        ({"max_iterations": 2.5}, TypeError, "rigid_options: max_iterations: expected an int, found float 2.5"),
        ({"trim": 5.0}, ValueError, r"rigid_options: trim: expected a fraction in \(0, 1\], found 5.0"),
        ({"trim": float("nan")}, ValueError, r"rigid_options: trim: expected a fraction in \(0, 1\], found nan"),
        ({"num_samples": 2}, ValueError, "rigid_options: num_samples: expected an int >= 3, found 2"),
        ({"point_to_plane": "yes"}, TypeError, "rigid_options: point_to_plane: expected a bool, found str"),
        ({"robust_scale": -1.0}, ValueError, "rigid_options: robust_scale: expected a float > 0"),
        ({"tolerance": float("inf")}, ValueError, "rigid_options: tolerance: expected a finite float >= 0"),
        ({"init": torch.eye(3)}, ValueError, r"rigid_options: init: expected shape \(4, 4\), found \(3, 3\)"),
        # Review I #9: a singular or NaN start passed and ICP died in torch's SVD ("linalg.svd: ... non-finite")
        ({"init": torch.zeros(4, 4)}, ValueError, "rigid_options: init: expected an invertible transform"),
        ({"init": torch.full((4, 4), float("nan"))}, ValueError, "rigid_options: init: expected finite values"),
    ],
)
def test_bad_rigid_options_are_refused_when_built(options, error, message):
    with pytest.raises(error, match=f"^{message}"):
        NonRigidOptions(rigid_options=options)


def test_good_rigid_options_are_kept_with_numpy_scalars():
    opts = NonRigidOptions(rigid_options={"max_iterations": np.int64(5), "trim": np.float32(0.5), "init": None})
    assert opts.rigid_options["max_iterations"] == 5 and opts.rigid_options["trim"] == 0.5
    assert NonRigidOptions(rigid_options={"robust_scale": float("inf")}).rigid_options["robust_scale"] == float("inf")


def test_register_rigid_uses_the_same_checks():
    box = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]), torch.tensor([[0, 1, 2], [0, 1, 3], [0, 2, 3]])
    with pytest.raises(TypeError, match=r"^max_iterations: expected an int, found str 'ten'"):
        register_rigid(box, box, max_iterations="ten")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^trim: expected a fraction in \(0, 1\], found 5.0"):
        register_rigid(box, box, trim=5.0)
    singular = torch.diag(torch.tensor([1.0, 1.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match=r"^init: expected an invertible transform .* determinant 0"):
        register_rigid(box, box, init=singular)
