"""CPU personalities: one machine playing other x86 CPUs, the cheap proof that a pinned figure holds elsewhere.

Each entry is the environment that makes torch, numpy and MKL take the kernels another CPU would take: torch's
``ATEN_CPU_CAPABILITY`` (its vectorised kernels: ``default`` is the scalar build), numpy's
``NPY_DISABLE_CPU_FEATURES`` (its dispatched SIMD loops, down to the baseline) and ``MKL_CBWR`` (MKL's
conditional-numerical-reproducibility branch). Variables a machine cannot honour (a feature it lacks) are no-ops.
``.ci/run`` runs the ``pinned`` tests again under :data:`OTHER_CPUS`; tests that compare bits across personalities
run their subject in subprocesses under each (:func:`run_as`).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

OTHER_CPUS: dict[str, dict[str, str]] = {
    # A CPU with no SIMD beyond the x86-64 baseline: torch's scalar kernels, numpy's baseline loops, MKL's
    # compatible branch.
    "scalar": {
        "ATEN_CPU_CAPABILITY": "default",
        "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL",
        "MKL_CBWR": "COMPATIBLE",
    },
    # An AVX2 CPU without AVX-512 (on an AVX-512 machine, a different set of kernels from its default).
    "avx2": {"ATEN_CPU_CAPABILITY": "avx2", "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL", "MKL_CBWR": "AVX2"},
}


def run_as(personality: dict[str, str], code: str, *, timeout: float = 600) -> str:
    """Run ``code`` in a new Python process under ``personality`` (from the repository root); its stdout."""
    env = {**os.environ, **personality, "PYTHONPATH": str(REPO)}
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=REPO, capture_output=True, text=True, timeout=timeout
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def main(argv: list[str]) -> int:
    """``python -m tests.cpu_personalities [--only NAME] COMMAND...``: run the command under each of :data:`OTHER_CPUS`.

    ``--only NAME`` runs it under that personality alone. Returns the first non-zero exit status, else 0
    (``.ci/run`` runs the ``pinned`` tests this way, and the whole suite under ``--only scalar``).
    """
    names = list(OTHER_CPUS)
    if argv[:1] == ["--only"]:
        if len(argv) < 3 or argv[1] not in OTHER_CPUS:
            found = argv[1] if len(argv) > 1 else "nothing"
            raise SystemExit(f"cpu_personalities: --only takes one of {names} and a command; found {found!r}")
        names, argv = [argv[1]], argv[2:]
    status = 0
    for name in names:
        personality = OTHER_CPUS[name]
        settings = " ".join(f"{k}={v}" for k, v in personality.items())
        print(f"\n=== CPU personality '{name}': {settings} ===", flush=True)
        code = subprocess.run(argv, env={**os.environ, **personality}, cwd=REPO).returncode
        status = status or code
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
