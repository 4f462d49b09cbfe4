"""The elementary functions of the built-in sequence: close to the exact values, and IEEE-defined operations only."""

import math

import mpmath
import numpy as np
import pytest

from torchmeshmetric.data import _portable_math as pm


def _ulps(got: np.ndarray, want: np.ndarray) -> float:
    return float(np.max(np.abs(got - want) / np.spacing(np.abs(want))))


def test_exp_log_within_two_ulps_of_the_exact_values():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.uniform(-700, 700, 20000), rng.uniform(-60, 0, 20000), [0.0, -1e-300, 1e-17]])
    want = np.array([math.exp(v) for v in x])  # glibc's exp: correctly rounded in practice, the reference
    assert _ulps(pm.exp(x), want) <= 2
    y = np.concatenate([np.exp(rng.uniform(-700, 700, 20000)), rng.uniform(1, 20, 20000), [1.0, 2.0, 0.5]])
    want = np.array([math.log(v) for v in y])
    nonzero = want != 0
    assert _ulps(pm.log(y)[nonzero], want[nonzero]) <= 2 and pm.log(np.array([1.0]))[0] == 0.0


def test_exp_limits_as_numpy():
    got = pm.exp(np.array([-800.0, 800.0, np.nan, -np.inf, np.inf]))
    assert got[0] == 0.0 and got[1] == np.inf and np.isnan(got[2]) and got[3] == 0.0 and got[4] == np.inf


@pytest.mark.parametrize("fn, ref", [(pm.sin_deg, mpmath.sin), (pm.cos_deg, mpmath.cos)])
def test_sin_cos_degrees(fn, ref):
    deg = np.concatenate([np.random.default_rng(1).uniform(-720, 720, 5000), np.arange(-360.0, 361.0, 15.0)])
    with mpmath.workdps(40):  # the exact values (math.radians alone rounds the argument by 1e-15 at 600 degrees)
        want = np.array([float(ref(mpmath.radians(mpmath.mpf(d)))) for d in deg])
    assert np.max(np.abs(fn(deg) - want)) <= 2 * np.finfo(np.float64).eps  # absolute: values cross zero
    quarter = np.arange(-8, 9) * 90.0
    exact = [float(round(ref(mpmath.radians(int(d))))) for d in quarter]
    assert np.array_equal(fn(quarter), exact)  # exactly 0 or +-1 at multiples of 90 degrees


def test_products_in_a_fixed_order():
    rng = np.random.default_rng(2)
    a, b, v = rng.normal(size=(4, 3, 3)), rng.normal(size=(4, 3, 3)), rng.normal(size=(4, 3))
    np.testing.assert_allclose(pm.matmul3(a, b), a @ b, rtol=0, atol=1e-15)
    np.testing.assert_allclose(pm.matvec3(a, v), np.einsum("bij,bj->bi", a, v), rtol=0, atol=1e-15)
    want = a[..., 0] * v[..., None, 0] + a[..., 1] * v[..., None, 1] + a[..., 2] * v[..., None, 2]
    assert np.array_equal(pm.matvec3(a, v), want)  # exactly this order of roundings
