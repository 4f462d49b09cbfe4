#!/usr/bin/env bash
# The GPU check of issue 39 (tests/benchmarks/gpu_check.py), in two calls of the device tool (docs/benchmarks.md,
# "GPU check"): a plain call gets an nvidia-h100-x1 (H100, ~78 GiB), an H200 only when named; the image has
# Python 3.12, torch 2.11 + CUDA 13, Triton 3.6, and reaches no registry.
#
#   tests/benchmarks/gpu_check.sh [--dry-run] [--mode main|warp] [--only a,b] [--budget S]
#
# Before the first GPU call, on a machine with network access: tests/benchmarks/gpu_check_wheels.sh (fills the
# ignored .gpu/wheels and .gpu/warp). Then, warp first (the issue's headline ratios), main right after it (the machine
# stays warm ~30 s between calls, so the second call starts no machine):
#   warp: carry [".gpu/wheels", ".gpu/warp"], command "tests/benchmarks/gpu_check.sh --mode warp", timeout_s 210
#   main: carry [".gpu/wheels"],              command "tests/benchmarks/gpu_check.sh",             timeout_s 360
# Budgets (the sections' own --budget; gpu_check.py stops itself 10 s past it, this script's hard stop, SIGINT,
# comes 15 s past it, SIGKILL 10 s later): warp 170 s, main 325 s. With one machine start of 60-120 s the two
# calls fit in the lease's 900 s with room for a rerun of the warp call.
#
# --dry-run: the same sections at small sizes on the CPU here (the CUDA-only ones report "skipped: no CUDA";
# cuda_tests runs the CPU twins of the -m cuda tests): the code paths, imports and output, not the GPU's figures
# or its compiled Triton kernels. Run it with a larger budget: GPU_CHECK_HARD_S=900 ... --dry-run --budget 850.
#
# The summary (gpu_check[_warp].json / .md, rewritten as each section and each row ends; logs) goes to $OUT (the
# device tool's folder) or ./out/gpu_check.
set -uo pipefail
cd "$(dirname "$0")/../.."
OUT="${OUT:-$PWD/out/gpu_check}"
mkdir -p "$OUT"
py="${PYTHON:-python3}"
site="$PWD/.gpu/site"
mode=main
case " $* " in *" --mode warp "*|*" --mode=warp "*) mode=warp ;; esac
export PYTHONPATH="$PWD:$site${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1

# The packages the image lacks come from the carried wheels (no registry there). Missing packages with no wheel to
# install them from stop the run here, loudly: every section would fail on its first import otherwise.
need() {  # need <folder> <python imports>: install the folder's wheels where the imports fail, or exit 2
    local folder=$1 imports=$2 wheels=()
    "$py" -c "import $imports" 2>/dev/null && return 0
    for w in "$folder"/*.whl; do [ -e "$w" ] && wheels+=("$w"); done
    if [ ${#wheels[@]} -eq 0 ]; then
        echo "gpu_check.sh: 'import $imports' fails and $folder holds no wheel: run tests/benchmarks/gpu_check_wheels.sh" \
             "on a machine with network access and carry $folder (docs/benchmarks.md, \"GPU check\")" >&2
        exit 2
    fi
    # No dependency resolution: each wheel is named in gpu_check_wheels.sh.
    "$py" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$site" "${wheels[@]}" \
        || { echo "gpu_check.sh: installing the wheels of $folder failed" >&2; exit 2; }
    if ! "$py" -c "import $imports" >&2; then
        echo "gpu_check.sh: 'import $imports' still fails after installing $folder (see above)" >&2
        exit 2
    fi
}
need .gpu/wheels "kornia, trimesh, fast_simplification, lazy_loader"
[ "$mode" = warp ] && need .gpu/warp "warp"

# The C++ extensions are built once per machine into the repository's ignored .gpu/ext (kept while the machine is warm).
export TORCH_EXTENSIONS_DIR="${TORCH_EXTENSIONS_DIR:-$PWD/.gpu/ext}"
export MAX_JOBS="${MAX_JOBS:-$(nproc)}"
# The hard stop: SIGINT 15 s past the default budget of the mode (GPU_CHECK_HARD_S to change it, e.g. for a dry run
# with a larger --budget), SIGKILL 10 s later. gpu_check.py writes what it finished and exits on the SIGINT.
if [ "$mode" = warp ]; then hard=185; else hard=340; fi
# Exit status (--preserve-status: gpu_check.py's, not timeout's 124): 0 every section ok or skipped, 1 a section
# failed, 2 the wheels (above), 3 stopped by the budget or the hard stop (what was finished is written), 137 SIGKILL.
timeout --preserve-status --signal=INT --kill-after=10 "${GPU_CHECK_HARD_S:-$hard}" "$py" tests/benchmarks/gpu_check.py --out "$OUT" "$@" 2>&1 \
    | tee "$OUT/gpu_check_${mode}_$(date +%H%M%S).log"
exit "${PIPESTATUS[0]}"
