"""Warnings a test gives on purpose, as pytest markers: one definition for every test that expects one."""

import pytest

#: A registration short on purpose (speed: a few steps of the first stage) gives ``register_nonrigid``'s
#: "not converged" warning; expected there, and convergence has its own tests.
expects_not_converged = pytest.mark.filterwarnings(
    "ignore:register_nonrigid. not converged:torchmeshmetric.registration.RegistrationWarning"
)
