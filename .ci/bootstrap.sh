#!/usr/bin/env bash
# Set up an environment for torchmeshmetric (if needed) and run the given command in it.
#
#   bash .ci/bootstrap.sh <command...>
#
# - Uses the active virtualenv/conda env when there is one (so a CUDA build of torch a user already has is kept);
#   otherwise creates ./.venv.
# - Installs torch only when none is importable, pinned (TORCH_SPEC, default torch==2.13.0) so pip never pulls an
#   unexpected multi-GB build; then installs this package (editable) with its runtime dependencies only, or with the
#   test extra when the command runs pytest (the README's test command). TORCHMESHMETRIC_EXTRAS=test,docs overrides.
# - Packages already installed are kept (pip upgrades nothing that already satisfies the requirements).
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ -z "${VIRTUAL_ENV:-}" && -z "${CONDA_PREFIX:-}" ]]; then
    if [[ ! -x .venv/bin/python ]]; then
        python3 -m venv .venv
    fi
    # shellcheck disable=SC1091
    . .venv/bin/activate
fi
extras="${TORCHMESHMETRIC_EXTRAS-}"
if [[ -z "${TORCHMESHMETRIC_EXTRAS+set}" ]]; then
    for arg in "$@"; do
        if [[ "$arg" == "pytest" || "$arg" == */pytest ]]; then
            extras="test"
        fi
    done
fi
stamp=".venv-installed-$(python -c 'import sys; print(sys.prefix.replace("/", "_"))')${extras:+-${extras//,/-}}"
if ! python -c "import torch" >/dev/null 2>&1; then
    python -m pip install -q "${TORCH_SPEC:-torch==2.13.0}"
fi
if [[ ! -f "$stamp" || pyproject.toml -nt "$stamp" ]]; then
    python -m pip install -q -e ".${extras:+[$extras]}"
    touch "$stamp"
fi
# The C++ extensions (torchmeshmetric/native) are built on first use with this compiler and ninja (a dependency):
# say loudly where there is none, since the library then runs its slower pure formulations.
if ! command -v "${CXX:-c++}" >/dev/null 2>&1; then
    echo "bootstrap: no C++ compiler (${CXX:-c++}) on PATH: the C++ extensions cannot be built; install one" \
        "(e.g. g++), or the library runs its slower pure formulations and IBSM is unavailable" >&2
fi
exec "$@"
