from __future__ import annotations

import numpy as np
import pytest
import torch

from torchmeshmetric._checks import DTypeError, NonFiniteError, ShapeError
from torchmeshmetric.temporal import kg_error, kso_error


def _oracle_case() -> tuple[torch.Tensor, torch.Tensor]:
    """CraGL Hyperspectral-Inverse-Skinning error_compare.py's seeded case, as (F, V, 3) (theirs is (3, V, F))."""
    np.random.seed(0)
    a = np.random.random((3, 100, 40))
    noise = np.random.random((3, 100, 40)) * 0.1
    return torch.from_numpy(a.transpose(2, 1, 0).copy()), torch.from_numpy((a + noise).transpose(2, 1, 0).copy())


def test_kg_and_kso_equal_the_reference_on_its_seeded_case() -> None:
    # The figures error_compare.py prints for this case (commit c9ae7ad of CraGL/Hyperspectral-Inverse-Skinning).
    a, r = _oracle_case()
    assert abs(kg_error(a, r).item() - 20.060768826277556) < 1e-12
    assert abs(kso_error(a, r).item() - 29.04106103892919) < 1e-12


def _numpy_kg(a: np.ndarray, b: np.ndarray) -> float:
    return float(100 * np.linalg.norm(a - b) / np.linalg.norm(a - a.mean(axis=1, keepdims=True)))


def test_batch_equals_items_and_float32_promotes() -> None:
    a, r = _oracle_case()
    batch_a, batch_r = torch.stack([a, a * 2]), torch.stack([r, r * 2 + 1])
    kg = kg_error(batch_a, batch_r)
    assert kg.shape == (2,)
    assert kg[0].item() == kg_error(a, r).item()
    assert abs(kg[1].item() - _numpy_kg(batch_a[1].numpy(), batch_r[1].numpy())) < 1e-12
    assert kg_error(a.float(), r).dtype == torch.float64


def test_kso_scale_is_the_reference_normalisation() -> None:
    a, r = _oracle_case()
    first = a[0].numpy()
    half_diagonal = 0.5 * np.linalg.norm(first.max(0) - first.min(0))
    assert abs(kso_error(a, r, scale=True).item() - kso_error(a, r).item() / half_diagonal) < 1e-12


def test_invariants() -> None:
    a, r = _oracle_case()
    assert kg_error(a, a).item() == 0.0 and kso_error(a, a).item() == 0.0
    q, _ = torch.linalg.qr(torch.randn(3, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(1)))
    t = torch.tensor([0.3, -2.0, 5.0], dtype=torch.float64)
    assert abs(kg_error(a @ q.T + t, r @ q.T + t).item() - kg_error(a, r).item()) < 1e-12
    assert abs(kso_error(a @ q.T + t, r @ q.T + t).item() - kso_error(a, r).item()) < 1e-12
    # KSO ignores a per-frame translation of the distorted animation (each frame is centred); KG does not.
    shifted = r + torch.linspace(0, 1, r.shape[0], dtype=torch.float64)[:, None, None]
    assert abs(kso_error(a, shifted).item() - kso_error(a, r).item()) < 1e-12
    assert kg_error(a, shifted).item() > kg_error(a, r).item()


def test_gradients_float64() -> None:
    a, r = _oracle_case()
    a, r = a[:3, :8].clone().requires_grad_(True), r[:3, :8].clone().requires_grad_(True)
    assert torch.autograd.gradcheck(kg_error, (a, r))
    assert torch.autograd.gradcheck(kso_error, (a, r))


def test_bad_input_is_named() -> None:
    a, r = _oracle_case()
    with pytest.raises(ShapeError, match="distorted: expected the shape of original"):
        kg_error(a, r[:, :50])
    with pytest.raises(ShapeError, match=r"original: expected shape \(\.\.\., F, V, 3\)"):
        kso_error(a[..., :2], r[..., :2])
    with pytest.raises(DTypeError, match="original"):
        kg_error(a.long(), r)
    bad = r.clone()
    bad[0, 0, 0] = float("nan")
    with pytest.raises(NonFiniteError, match="distorted"):
        kg_error(a, bad)
    with pytest.raises(TypeError, match=r"original: expected a torch\.Tensor"):
        kg_error(a.numpy(), r)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="single point"):
        kg_error(torch.zeros(2, 1, 3), torch.ones(2, 1, 3))


def test_scale_is_a_bool() -> None:
    a = torch.rand(2, 5, 3, dtype=torch.float64)
    with pytest.raises(TypeError, match="scale: expected a bool, found str 'no'"):  # a truthy string scaled
        kso_error(a, a, scale="no")  # type: ignore[arg-type]


def test_complex_coordinates_are_named_as_complex() -> None:
    # Found by review: a complex tensor was told to "convert integer coordinates with .float()".
    from torchmeshmetric._checks import DTypeError

    x = torch.zeros(2, 4, 3, dtype=torch.complex128)
    with pytest.raises(
        DTypeError, match=r"original: expected a real floating-point tensor .* found dtype torch.complex128"
    ):
        kg_error(x, x)
