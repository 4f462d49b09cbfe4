#!/usr/bin/env bash
# Fetch, on a machine with network access, the wheels that tests/benchmarks/gpu_check.sh installs on the GPU machine
# (which reaches no registry): the packages its image lacks, for its Python (3.12, x86-64), into .gpu/wheels, and
# NVIDIA Warp 1.2.0 (the peer) into .gpu/warp. Both folders are ignored by git; name them in the device call's carry.
#
# Warp's wheel is 60.5 MiB, too big to travel with the others under the 64 MiB limit of a call, so it is slimmed:
# warp-clang.so (Warp's CPU compiler: Warp disables its CPU device when the file is absent, warp/context.py) and the
# bundled examples and tests are left out. What remains (warp.so, the CUDA runtime of Warp) is byte for byte the
# published one.
set -euo pipefail
cd "$(dirname "$0")/../.."
py="${PYTHON:-python3}"
target=(--only-binary=:all: --python-version 3.12 --implementation cp --platform manylinux_2_28_x86_64
        --platform manylinux_2_27_x86_64 --platform manylinux_2_24_x86_64 --platform manylinux_2_17_x86_64
        --platform manylinux2014_x86_64 --platform manylinux1_x86_64)
mkdir -p .gpu/wheels .gpu/warp
# The runtime dependencies the GPU image lacks (KINDS.md lists what it has): pinned to the versions tested here.
"$py" -m pip download -q --no-deps "${target[@]}" -d .gpu/wheels \
    kornia==0.9.0 kornia_rs==0.2.0 trimesh==5.2.0 fast-simplification==0.2.0 lazy_loader==0.6
tmp=$(mktemp -d)
"$py" -m pip download -q --no-deps "${target[@]}" -d "$tmp" warp-lang==1.2.0
"$py" - "$tmp" .gpu/warp <<'PY'
import sys, zipfile
from pathlib import Path

src_dir, dst_dir = Path(sys.argv[1]), Path(sys.argv[2])
(wheel,) = src_dir.glob("warp_lang-*.whl")
dropped = ("warp/bin/warp-clang.so", "warp/examples/", "warp/tests/")
with zipfile.ZipFile(wheel) as zin, zipfile.ZipFile(dst_dir / wheel.name, "w", zipfile.ZIP_DEFLATED) as zout:
    for item in zin.infolist():
        if item.filename.startswith(dropped):
            continue
        data = zin.read(item.filename)
        if item.filename.endswith(".dist-info/RECORD"):
            keep = [ln for ln in data.decode().splitlines() if not ln.startswith(dropped)]
            data = ("\n".join(keep) + "\n").encode()
        zout.writestr(item, data)
print(f"{wheel.name}: {wheel.stat().st_size / 2**20:.1f} MiB -> {(dst_dir / wheel.name).stat().st_size / 2**20:.1f} MiB")
PY
rm -rf "$tmp"
du -sh .gpu/wheels .gpu/warp
