#!/usr/bin/env bash
# The GPU check of issue 39 (tests/benchmarks/gpu_check.py): one call, at most ~8 minutes on the H200.
#
#   tests/benchmarks/gpu_check.sh [--dry-run] [--mode main|warp] [--only a,b] [--budget S]
#
# Before the first GPU call, on a machine with network access: tests/benchmarks/gpu_check_wheels.sh (fills the
# ignored .gpu/wheels and .gpu/warp). Then, with the device tool (docs/benchmarks.md#gpu-check):
#   main: carry [".gpu/wheels"],              command "tests/benchmarks/gpu_check.sh",             timeout_s 500
#   warp: carry [".gpu/wheels", ".gpu/warp"], command "tests/benchmarks/gpu_check.sh --mode warp", timeout_s 300
# The summary (gpu_check[_warp].json / .md, logs) goes to $OUT (the device tool's folder) or ./out/gpu_check.
set -uo pipefail
cd "$(dirname "$0")/../.."
OUT="${OUT:-$PWD/out/gpu_check}"
mkdir -p "$OUT"
py="${PYTHON:-python3}"
site="$PWD/.gpu/site"
wheels=()
# The carried wheels are installed only where the packages are missing (a dry run here has them already).
if ! "$py" -c "import kornia, trimesh, fast_simplification, lazy_loader" 2>/dev/null; then
    for w in .gpu/wheels/*.whl; do [ -e "$w" ] && wheels+=("$w"); done
fi
case " $* " in *" warp "*|*"--mode=warp"*)
    if ! "$py" -c "import warp" 2>/dev/null; then
        for w in .gpu/warp/*.whl; do [ -e "$w" ] && wheels+=("$w"); done
    fi ;;
esac
if [ ${#wheels[@]} -gt 0 ]; then
    # No registry there: the carried wheels only, no dependency resolution (each is named in gpu_check_wheels.sh).
    "$py" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$site" "${wheels[@]}" \
        || { echo "gpu_check.sh: installing the carried wheels failed" >&2; exit 2; }
fi
export PYTHONPATH="$PWD:$site${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
# The C++ extensions are built once per machine into the repository's ignored .gpu/ext (kept while the machine is warm).
export TORCH_EXTENSIONS_DIR="${TORCH_EXTENSIONS_DIR:-$PWD/.gpu/ext}"
export MAX_JOBS="${MAX_JOBS:-$(nproc)}"
# A hard stop a little past the script's own budget (430 s by default; GPU_CHECK_HARD_S to change it, e.g. for a
# dry run with a larger --budget): what was written under $OUT stays.
timeout --signal=INT "${GPU_CHECK_HARD_S:-470}" "$py" tests/benchmarks/gpu_check.py --out "$OUT" "$@" 2>&1 | tee "$OUT/gpu_check_$(date +%H%M%S).log"
exit "${PIPESTATUS[0]}"
