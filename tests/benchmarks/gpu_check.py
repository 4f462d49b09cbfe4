"""One prepared check of the library on a GPU (issue 39); run through ``tests/benchmarks/gpu_check.sh``.

Modes (one call each, on the same lease; the sections of each run most valuable first):

* ``warp`` (the issue's headline ratios): exact point->mesh distance at 40k and 630k faces with 1M queries (build +
  query, query only) and the ``TemporalConsistencyLoss`` training step, against NVIDIA Warp (``mesh_query_point``),
  ours timed again in the same process so that every ratio is a same-run ratio.
* ``main``: every C++ extension built at once, the Triton kernels compiled for the GPU against the same-device brute
  force and the CPU float64 results, point->mesh at 40k and 630k faces (build + query, query on a kept index), the
  training step (forward + backward, 8 pairs, ``tests/benchmarks/test_temporal_loss_bench.py``'s case) with its
  host-device synchronisations counted, the registration of a captured-like ~20k-vertex pair on CUDA, the suite's
  CUDA tests (``pytest -m cuda``), the C++ CPU kernels' thread scaling (1 -> 16 threads, 630k-face query), the
  metrics in a Lightning ``Trainer(accelerator="gpu")`` loop with logging, and last a ``torch.compile``d brute force.

``--dry-run`` runs everything at small sizes on whatever device there is (on a CPU machine the CUDA-only parts
report ``skipped: no CUDA``, and ``cuda_tests`` runs the CPU twins of the tests ``-m cuda`` selects). Every section
is timed, guarded (a failure is reported, the next section runs) and written (atomically) to
``gpu_check[_warp].json`` / ``.md`` under ``--out`` when it starts, as each of its rows or measurements finishes, and
when it ends. The script stops itself at its ``--budget`` (SIGALRM); a SIGINT (``timeout --signal=INT``, the hard
stop of ``gpu_check.sh``) or SIGTERM marks the running section ``interrupted (hard stop)`` and the rest ``not run``,
and keeps everything finished.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import platform
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import torch

ROOT = Path(__file__).resolve().parents[2]
# Full sizes: torus sections (major, minor) -> 2 * major * minor faces; 1M query points.
FULL = {"sizes": {"40k": (200, 100), "630k": (790, 400)}, "queries": 1_000_000, "threads": [1, 2, 4, 8, 16]}
DRY = {"sizes": {"2k": (40, 25), "8k": (80, 50)}, "queries": 20_000, "threads": [1, 2]}
GOALS = {
    "build_query_vs_warp": 1.0,  # ours / Warp, build + query, at most
    "training_step_vs_warp": 0.5,  # ours / Warp, at most
    "registration_20k_s": 0.25,  # seconds, at most
    "cpu_16_vs_1_thread": 10.0,  # speed-up, at least
}


# ----------------------------------------------------------------------------------------------------- utilities


def sync(device: str | torch.device) -> None:
    if torch.device(device).type == "cuda":
        torch.cuda.synchronize()


def timed(fn: Callable[[], Any], device: str, rounds: int, warmup: int = 1) -> dict[str, Any]:
    """Best and median wall time of ``fn`` (synchronised), and the peak of torch's CUDA allocator during the rounds."""
    for _ in range(warmup):
        fn()
    sync(device)
    cuda = torch.device(device).type == "cuda"
    if cuda:
        torch.cuda.reset_peak_memory_stats()
        base = torch.cuda.memory_allocated()
    times = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        fn()
        sync(device)
        times.append(time.perf_counter() - t0)
    out: dict[str, Any] = {"best_s": min(times), "median_s": statistics.median(times), "rounds": rounds}
    if cuda:
        out["peak_mib"] = torch.cuda.max_memory_allocated() / 2**20
        out["peak_above_inputs_mib"] = (torch.cuda.max_memory_allocated() - base) / 2**20
    return out


def torus(major: int, minor: int, dtype: torch.dtype = torch.float32) -> tuple[torch.Tensor, torch.Tensor]:
    """A closed torus (radii 1 and 0.3) of ``2 * major * minor`` faces, without trimesh (the peer call lacks it)."""
    u = torch.arange(major, dtype=torch.float64) * (2 * math.pi / major)
    v = torch.arange(minor, dtype=torch.float64) * (2 * math.pi / minor)
    uu, vv = torch.meshgrid(u, v, indexing="ij")
    ring = 1.0 + 0.3 * torch.cos(vv)
    verts = torch.stack([ring * torch.cos(uu), ring * torch.sin(uu), 0.3 * torch.sin(vv)], -1).reshape(-1, 3)
    i, j = torch.meshgrid(torch.arange(major), torch.arange(minor), indexing="ij")
    a, b = i * minor + j, ((i + 1) % major) * minor + j
    c, d = ((i + 1) % major) * minor + (j + 1) % minor, i * minor + (j + 1) % minor
    faces = torch.cat([torch.stack([a, b, c], -1).reshape(-1, 3), torch.stack([a, c, d], -1).reshape(-1, 3)])
    return verts.to(dtype), faces


def near_points(n: int, seed: int = 0) -> torch.Tensor:
    """``n`` points within ~1% of the torus's minor radius of its surface (uniform angles, Gaussian offset)."""
    g = torch.Generator().manual_seed(seed)
    u, v = (torch.rand(n, generator=g, dtype=torch.float64) * 2 * math.pi for _ in range(2))
    r = 0.3 + 0.003 * torch.randn(n, generator=g, dtype=torch.float64)
    ring = 1.0 + r * torch.cos(v)
    return torch.stack([ring * torch.cos(u), ring * torch.sin(u), r * torch.sin(v)], -1).float()


@cache
def point_case(size: str, sections: tuple[int, int], queries: int) -> dict[str, torch.Tensor]:
    verts, faces = torus(*sections)
    return {"verts": verts, "faces": faces, "points": near_points(queries)}


def compiled_bruteforce(verts: torch.Tensor, faces: torch.Tensor, compile: bool) -> Callable[[torch.Tensor], Any]:
    """Exact distance by brute force against every face, ``torch.compile``d.

    The squared distance is the library's own expression (``region_candidates``: the four Voronoi-region candidates
    of Ericson's closest point, the least of them), without its input checks (a check reads a value back and would
    break the compiled graph). Query rows go in fixed-size chunks (one compiled shape; the last chunk padded) of
    5e7 point-face pairs on CUDA (~6 GB if the compiler fused nothing: ~30 float32 values per pair), 2e6 on the CPU.
    """
    from torchmeshmetric.kernels.triangle import region_candidates

    a, b, c = (verts[faces[:, k]] for k in range(3))
    ab, ac, bc = b - a, c - a, c - b
    rows = max(1, min(65536, (50_000_000 if verts.is_cuda else 2_000_000) // faces.shape[0]))

    def chunk(p: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        q = p[:, None, :]
        sq = region_candidates(q - a[None], q - b[None], ab[None], ac[None], bc[None])[-1].amin(-1)
        best, idx = sq.min(dim=1)
        return best.sqrt(), idx

    fn = torch.compile(chunk, dynamic=False) if compile else chunk

    def run(points: torch.Tensor, max_chunks: int | None = None) -> tuple[torch.Tensor, int, int]:
        n = points.shape[0]
        total = -(-n // rows)
        padded = torch.cat([points, points[:1].expand(total * rows - n, 3)]) if total * rows != n else points
        done = total if max_chunks is None else min(total, max_chunks)
        out = [fn(padded[i * rows : (i + 1) * rows])[0] for i in range(done)]
        return torch.cat(out)[: min(n, done * rows)], done, total

    return run


def sync_counter() -> Any:
    """Context manager counting host-device synchronisations: CUDA's sync debug mode (one warning per sync)."""

    class Counter:
        def __enter__(self) -> Counter:
            self._w = warnings.catch_warnings(record=True)
            self.records = self._w.__enter__()
            warnings.simplefilter("always")
            torch.cuda.set_sync_debug_mode("warn")
            return self

        def __exit__(self, *exc: Any) -> None:
            torch.cuda.set_sync_debug_mode("default")
            self._w.__exit__(*exc)
            msgs = [str(r.message) for r in self.records if "synchroniz" in str(r.message).lower()]
            self.count = len(msgs)
            self.kinds = sorted({m.split("\n")[0][:120] for m in msgs})

    return Counter()


class _ReadInBackward(torch.autograd.Function):
    """Identity whose backward reads a value back (one sync on the autograd engine's device thread)."""

    @staticmethod
    def forward(ctx: Any, x: torch.Tensor) -> torch.Tensor:
        return x.clone()

    @staticmethod
    def backward(ctx: Any, grad: torch.Tensor) -> torch.Tensor:
        float(grad.sum())
        return grad


def _sync_counter_control(device: str) -> dict[str, bool]:
    """Whether :func:`sync_counter` sees a known sync in forward code and one in a backward pass.

    The backward's warnings are raised on the autograd engine's CUDA thread and replayed on the caller's; a count of
    0 per step would otherwise be ambiguous (review M, finding 10).
    """
    x = torch.ones(4, device=device, requires_grad=True)
    with sync_counter() as fwd:
        float(x.detach().sum())
    with sync_counter() as bwd:
        _ReadInBackward.apply(x).sum().backward()
    return {"forward": fwd.count >= 1, "backward": bwd.count >= 1}


# ------------------------------------------------------------------------------------------------------ the run


class Check:
    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.dry = args.dry_run
        self.sizes = DRY if self.dry else FULL
        self.cuda = torch.cuda.is_available()
        self.device = "cuda" if self.cuda else "cpu"
        self.deadline = time.monotonic() + args.budget
        self.live: dict[str, Any] = {}  # the running section's result, filled as it goes
        self.out = Path(args.out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.name = "gpu_check" if args.mode == "main" else "gpu_check_warp"
        self.results: dict[str, Any] = {}
        # torch.compile of the brute force: on in a full run; a dry run compiles only when asked (--compile): the
        # CPU inductor's C++ build of the kernel takes minutes on a loaded 2-core machine.
        self.compile = not args.no_compile and (not self.dry or args.compile)

    def left(self) -> float:
        return self.deadline - time.monotonic()

    def section(self, name: str, fn: Callable[[], dict[str, Any] | None], *, cuda: bool = False, need_s: float = 15):
        """Run one section, guarded and timed; its result is written when it starts, as it goes, and when it ends.

        A section fills ``self.live`` (its result) and calls :meth:`write` after each row or measurement, so a hard
        stop keeps those; ``KeyboardInterrupt`` (SIGINT, and SIGTERM / SIGALRM turned into it) is recorded as
        ``interrupted (hard stop)`` with the time spent, then re-raised to end the run.
        """
        if cuda and not self.cuda:
            self.results[name] = {"status": "skipped: no CUDA"}
        elif self.left() < need_s:
            self.results[name] = {"status": f"skipped: time budget ({self.left():.0f} s left, needs ~{need_s:.0f})"}
        else:
            print(f"[gpu_check] {name} ({self.left():.0f} s left)", flush=True)
            t0 = time.perf_counter()
            live: dict[str, Any] = {"status": "running"}
            self.live = self.results[name] = live
            self.write()
            try:
                r = fn() or {}
                if r is not live:
                    live.update(r)
                if live["status"] == "running":
                    live["status"] = "ok"
            except KeyboardInterrupt as stop:
                live["status"] = f"interrupted (hard stop: {str(stop) or 'SIGINT'})"
                live["seconds"] = round(time.perf_counter() - t0, 2)
                print(f"[gpu_check] {name}: interrupted after {live['seconds']} s", flush=True)
                self.write()
                raise
            except Exception as e:  # a failing section is reported; the next one runs
                live["status"] = f"failed: {type(e).__name__}: {str(e)[:500]}"
                live["traceback"] = traceback.format_exc()[-4000:]
            live["seconds"] = round(time.perf_counter() - t0, 2)
            print(f"[gpu_check] {name}: {live['status']} in {live['seconds']} s", flush=True)
        self.write()

    # ------------------------------------------------------------------------------------------------ sections

    def environment(self) -> dict[str, Any]:
        env: dict[str, Any] = {
            "mode": self.args.mode,
            "dry_run": self.dry,
            "python": platform.python_version(),
            "torch": torch.__version__,
            "cuda_available": self.cuda,
            "cpu_count": os.cpu_count(),
            "torch_threads": torch.get_num_threads(),
            "TRITON_INTERPRET": os.environ.get("TRITON_INTERPRET"),
        }
        for mod in ("triton", "lightning", "torchmetrics", "kornia", "trimesh", "fast_simplification", "warp"):
            try:
                env[mod] = getattr(__import__(mod), "__version__", "?")
            except Exception as e:
                env[mod] = f"absent ({type(e).__name__})"
        if self.cuda:
            p = torch.cuda.get_device_properties(0)
            env |= {"gpu": p.name, "capability": f"{p.major}.{p.minor}", "gpu_mib": p.total_memory // 2**20}
            try:
                smi = subprocess.run(["nvidia-smi"], capture_output=True, text=True, timeout=20)
                env["nvidia_smi"] = smi.stdout[-2500:]
            except Exception as e:
                env["nvidia_smi"] = f"failed: {e}"
        return env

    def native_build(self) -> dict[str, Any]:
        """Build every C++ extension the run needs, all at once, before anything uses one.

        ``bvh``: the CPU rows, the CPU float64 references, the registration and the bench case; ``pcc`` and ``ibsm``:
        ``tests/mpeg/test_losses.py``'s CUDA cases (their first use would otherwise build them inside ``cuda_tests``'s
        timeout, the other workers waiting on the lock); ``pcqm``: the rest of the suite. Each builds in its own
        process (``native.load`` builds one extension at a time per process), so the four take about as long as the
        slowest: an extension's translation units are its only parallelism. ``MAX_JOBS`` is ``nproc``
        (``gpu_check.sh``). Warp mode needs ``bvh`` only but builds all four as well (the same wall time on 16
        cores): the builds stay in the ignored ``.gpu/ext`` of the warm machine, and the main call right after it
        finds them built.
        """
        from torchmeshmetric import native

        names = list(native.EXTENSIONS)
        r = self.live
        r["extensions"] = {n: {"cached": native.ready(n)} for n in names}
        self.write()
        t0 = time.perf_counter()
        code = "import sys; from torchmeshmetric import native; native.load(sys.argv[1])"
        with contextlib.ExitStack() as files:
            # Output to unnamed files, not pipes: a build's compiler warnings could fill a pipe nobody reads yet.
            logs = {
                n: files.enter_context(tempfile.TemporaryFile("w+")) for n in names if not r["extensions"][n]["cached"]
            }
            procs = {
                n: subprocess.Popen([sys.executable, "-c", code, n], cwd=ROOT, stdout=log, stderr=subprocess.STDOUT)
                for n, log in logs.items()
            }
            self._wait_builds(procs, logs, t0)
        # Load them here too (an import of the finished builds); a failure is the section's status.
        for n in names:
            t1 = time.perf_counter()
            r["extensions"][n]["loaded"] = native.try_load(n) is not None
            r["extensions"][n]["load_s"] = round(time.perf_counter() - t1, 2)
        r["wall_s"] = round(time.perf_counter() - t0, 1)
        bad = [n for n in names if not r["extensions"][n]["loaded"]]
        if bad:
            r["status"] = f"failed: not built: {', '.join(bad)}"
        return r

    def _wait_builds(self, procs: dict[str, subprocess.Popen[bytes]], logs: dict[str, Any], t0: float) -> None:
        """Record each build's time as it ends; kill those still running on a hard stop (no build left behind)."""
        r = self.live["extensions"]
        try:
            pending = dict(procs)
            while pending:
                for n, proc in list(pending.items()):
                    if proc.poll() is None:
                        continue
                    r[n]["build_s"] = round(time.perf_counter() - t0, 1)
                    r[n]["returncode"] = proc.returncode
                    if proc.returncode != 0:
                        logs[n].seek(0)
                        r[n]["output_tail"] = logs[n].read()[-1500:]
                    del pending[n]
                    self.write()
                time.sleep(0.2)
        finally:
            for proc in procs.values():
                if proc.poll() is None:
                    proc.kill()
                    proc.wait()

    def _cpu_twins(self) -> list[str]:
        """The CPU twins of the tests ``-m cuda`` selects (``[..-cuda-..]`` -> ``[..-cpu-..]``) that exist.

        A dry run on a CPU cannot run the CUDA cases; their twins exercise the same code on the CPU and import every
        file the device run imports (CUDA-only tests without a twin, such as
        ``test_cuda_compiled_kernel_matches_bruteforce``, are only imported).
        """
        base = [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:randomly",
                "--ignore=tests/benchmarks", "-o", "addopts=-p no:cacheprovider"]  # fmt: skip

        def ids(*args: str) -> list[str]:
            out = subprocess.run([*base, *args], cwd=ROOT, capture_output=True, text=True, timeout=300).stdout
            return [ln.strip() for ln in out.splitlines() if "::" in ln and not ln.startswith(" ")]

        cuda = ids("-m", "cuda", "tests")
        files = sorted({i.split("::")[0] for i in cuda})
        present = set(ids("-m", "not cuda", *files)) if files else set()

        def twin(node: str) -> str:
            if "[" not in node:
                return node
            head, params = node.split("[", 1)
            return head + "[" + "-".join("cpu" if p == "cuda" else p for p in params[:-1].split("-")) + "]"

        self.live["cuda_selected"] = len(cuda)
        self.live["cuda_files"] = files
        return sorted({twin(i) for i in cuda} & present)

    def cuda_tests(self) -> dict[str, Any]:
        r = self.live
        junit = self.out / "pytest_cuda.xml"
        # On a GPU the suite's CUDA tests; in a dry run on the CPU the CPU twins of the same selection.
        select = self._cpu_twins() if not self.cuda else ["-m", "cuda", "tests"]
        if not self.cuda:
            r["cpu_twins_run"] = len(select)
            self.write()
        workers = "0" if not self.cuda else "4"  # 16 cores there: the CPU float64 references in parallel
        cmd = [sys.executable, "-m", "pytest", *select, "--ignore=tests/benchmarks", "-q", "-n", workers,
               "--continue-on-collection-errors", f"--junitxml={junit}", "-p", "no:randomly",
               "-o", "addopts=--benchmark-skip -p no:cacheprovider"]  # fmt: skip
        # What is left, less what the sections after it need (cpu_threads ~30 s): the tests' share of the budget.
        timeout = max(30.0, self.left() - 35) if self.cuda else max(30.0, self.left() - 60)
        r["timeout_s"] = round(timeout)
        t0 = time.perf_counter()
        with (self.out / "pytest_cuda.log").open("w") as log:
            # Its own session, so that a timeout or a hard stop ends the xdist workers as well (a killed pytest leaves
            # its workers running otherwise, holding the GPU and the cores).
            proc = subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
            try:
                rc: int | str = proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                rc = "timeout"
            finally:
                if proc.poll() is None:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
        r["selection"] = "-m cuda tests" if self.cuda else f"{len(select)} CPU twins (node ids)"
        r["returncode"] = rc
        r["wall_s"] = round(time.perf_counter() - t0, 1)
        if junit.exists():
            suite = ET.parse(junit).getroot()
            suite = suite if suite.tag == "testsuite" else suite[0]
            r |= {k: int(suite.get(k, 0)) for k in ("tests", "failures", "errors", "skipped")}
            r["failed_tests"] = [
                f"{tc.get('classname')}::{tc.get('name')}"
                for tc in suite.iter("testcase")
                if tc.find("failure") is not None or tc.find("error") is not None
            ][:40]
            slow = sorted(suite.iter("testcase"), key=lambda tc: -float(tc.get("time", 0)))[:5]
            r["slowest_tests_s"] = {f"{tc.get('classname')}::{tc.get('name')}": float(tc.get("time", 0)) for tc in slow}
            junit.unlink()  # the log has the details; $OUT brings back at most 8 files
        if rc != 0:
            r["status"] = f"failed: pytest returned {rc}"
        elif not self.cuda:
            r["status"] = "skipped: no CUDA (the CPU twins of the -m cuda selection ran and passed)"
        return r

    def triton_compiled(self) -> dict[str, Any]:
        """The Triton kernels compiled for this GPU: faces and distances against the same-device brute force (bit for
        bit) and against the CPU float64 result (tolerance 1e-6 x diagonal)."""
        from torchmeshmetric import MeshIndex, nearest_vertex_distance, point_mesh_distance
        from torchmeshmetric.kernels import select

        assert not os.environ.get("TRITON_INTERPRET"), "TRITON_INTERPRET is set: the kernels would be interpreted"
        c = point_case("triton", (120, 60), 200_000)
        v, f, p = c["verts"].cuda(), c["faces"].cuda(), c["points"][:200_000].cuda()
        r: dict[str, Any] = {"faces": int(f.shape[0]), "points": int(p.shape[0])}
        r["auto_backend"] = select.auto_backend_name(torch.device("cuda"), torch.float32, p.shape[0] * f.shape[0])
        t0 = time.perf_counter()
        got = point_mesh_distance(p, v, f, backend="triton")
        sync("cuda")
        r["first_call_s_with_compile"] = round(time.perf_counter() - t0, 3)
        brute = point_mesh_distance(p[:20000], v, f, backend="bruteforce")
        r["same_faces_as_cuda_bruteforce"] = bool(torch.equal(got.face_idx[:20000], brute.face_idx))
        r["same_dists_as_cuda_bruteforce"] = bool(torch.equal(got.dists[:20000], brute.dists))
        ref = point_mesh_distance(p[:20000].double().cpu(), c["verts"].double(), c["faces"])
        diag = float((c["verts"].amax(0) - c["verts"].amin(0)).norm())
        r["max_abs_diff_vs_cpu_float64_over_diag"] = (
            float((got.dists[:20000].cpu().double() - ref.dists).abs().max()) / diag
        )
        nv = nearest_vertex_distance(p, v, backend="triton")
        nref = nearest_vertex_distance(p[:20000].double().cpu(), c["verts"].double())
        r["nearest_max_abs_diff_vs_cpu_float64_over_diag"] = (
            float((nv.dists[:20000].cpu().double() - nref.dists).abs().max()) / diag
        )
        index = MeshIndex((v, f), backend="triton")
        index.point_mesh_distance(p[:1000])
        index.refit(v * 1.01)
        moved = point_mesh_distance(p[:20000], v * 1.01, f, backend="bruteforce")
        r["refit_same_dists_as_bruteforce"] = bool(torch.equal(index.point_mesh_distance(p[:20000]).dists, moved.dists))
        ok = (
            r["max_abs_diff_vs_cpu_float64_over_diag"] <= 1e-6
            and r["nearest_max_abs_diff_vs_cpu_float64_over_diag"] <= 1e-6
        )
        if not ok:
            r["status"] = "failed: float32 CUDA distances beyond 1e-6 x diagonal of the CPU float64 ones"
        return r

    def registration(self) -> dict[str, Any]:
        from tests.registration.gt_pairs import make_captured_pair
        from torchmeshmetric.registration import register_nonrigid

        spacing = 0.05 if self.dry else 0.0135
        pair = make_captured_pair("medium", spacing)
        src = (torch.tensor(pair.source[0]), torch.tensor(pair.source[1]))
        tgt = (torch.tensor(pair.target[0]), torch.tensor(pair.target[1]))
        r = self.live
        r |= {"source_vertices": int(src[0].shape[0]), "target_vertices": int(tgt[0].shape[0])}
        r["runs"] = runs = {}
        # A dry run on a shared CPU: one thread (every parallel region of a loaded machine waits for its slowest core).
        threads = 1 if self.dry else len(os.sched_getaffinity(0))
        for dev, rounds in ((self.device, 1 if self.dry else 3), ("cpu", 1 if self.cuda else 0)):
            if rounds == 0:
                continue
            torch.set_num_threads(threads)
            last: dict[str, Any] = {}

            def go(dev: str = dev, last: dict[str, Any] = last) -> None:
                out = register_nonrigid(
                    src, tgt, device=dev, generator=torch.Generator().manual_seed(0), num_threads=None
                )
                last["r"] = out

            t = timed(go, dev, rounds=rounds, warmup=0 if self.dry else 1)
            reg = last["r"]
            runs[dev] = t | {
                "converged": bool(reg.converged),
                "reason": reg.reason,
                "gt_rmse_percent_of_diagonal": 100 * pair.gt_rmse(reg.verts),
                "timings": {k: round(float(v), 4) for k, v in reg.timings.items()},
            }
            self.write()
        if self.cuda:
            r["goal_20k_le_0.25_s"] = runs["cuda"]["best_s"] <= GOALS["registration_20k_s"]
            if not runs["cuda"]["converged"]:
                r["status"] = f"failed: not converged on CUDA ({runs['cuda']['reason']})"
        return r

    def _bench_module(self) -> Any:
        if self.dry:
            os.environ.setdefault("TMM_BENCH_PAIRS", "2")
            os.environ.setdefault("TMM_BENCH_RESOLUTION", "48")
            os.environ.setdefault("TMM_BENCH_SIMPLIFIED_FACES", "1500")
        import tests.benchmarks.test_temporal_loss_bench as bench

        return bench

    def temporal_loss(self) -> dict[str, Any]:
        from torchmeshmetric.metrics import TemporalConsistencyLoss, temporal_consistency_loss

        bench = self._bench_module()
        c = bench.case()
        dev = self.device
        state = bench.Step(dev, "registration")
        loss_fn = TemporalConsistencyLoss()

        def step() -> None:
            state.move()
            a = state.args()
            loss_fn(*a[:4], registration=a[4]).backward()

        r = self.live
        r |= {
            "pairs": bench.PAIRS,
            "simplified_verts": int(c["simplified"][1].num_verts),
            "original_faces": int(c["originals"][1].num_faces),
            "device": dev,
        }
        r["kept_indexes"] = timed(step, dev, rounds=5, warmup=2)
        self.write()

        def rebuilt() -> None:
            state.move()
            temporal_consistency_loss(*state.args()).backward()

        r["rebuilt_indexes"] = timed(rebuilt, dev, rounds=3, warmup=1)
        self.write()
        # Host-device synchronisations of one warmed step: CUDA's sync debug mode on a GPU; on a CPU the aten ops
        # that would synchronise (tests/metrics/test_loss_syncs.py's counter).
        if self.cuda:
            sync(dev)
            with sync_counter() as sc:
                step()  # the warnings are raised by the host calls: no synchronize inside (it would count too)
            sync(dev)
            r["syncs_per_step"] = sc.count
            r["sync_kinds"] = sc.kinds
            r["sync_counter_sees_known_syncs"] = _sync_counter_control(dev)
        else:
            from tests.metrics.test_loss_syncs import CountSyncs

            with CountSyncs() as counter:
                step()
            r["syncing_aten_ops_per_step"] = dict(counter.ops)
        self.write()
        # Value and gradients against the CPU float64 loss of the same frames and warp.
        a = state.args()
        for v in state.verts:
            v.grad = None
        got = loss_fn(*a[:4], registration=a[4])
        got.backward()
        g32 = [v.grad.detach().cpu().double() for v in state.verts]
        v64 = [v.detach().cpu().double().requires_grad_(True) for v in state.verts]
        f64 = [f.cpu() for f in state.faces]
        s = list(zip(v64, f64, strict=True))
        o64 = [o.to("cpu").to(dtype=torch.float64) for o in c["originals"]]
        w64 = c["warp"].to("cpu", torch.float64)
        ref = temporal_consistency_loss(s[1:], s[:-1], o64[1:], o64[:-1], [w64] * bench.PAIRS)
        ref.backward()
        g64 = torch.cat([v.grad for v in v64 if v.grad is not None])
        g32c = torch.cat([g for g, v in zip(g32, v64, strict=True) if v.grad is not None])
        r["loss"] = float(got.detach())
        r["loss_rel_diff_vs_cpu_float64"] = abs(float(got.detach()) - float(ref.detach())) / abs(float(ref.detach()))
        r["grad_rel_norm_diff_vs_cpu_float64"] = float((g32c - g64).norm() / g64.norm())
        return r

    def lightning(self) -> dict[str, Any]:
        import tests.metrics.test_lightning as tl

        items = [
            (simp, (torch.tensor(ref.vertices), torch.tensor(ref.faces)))  # tensors: Lightning moves them to the GPU
            for simp, ref in tl._items()
        ]
        module = tl.Module(items)
        logger = tl.MemoryLogger()
        trainer = tl._trainer(
            accelerator="gpu" if self.cuda else "cpu",
            devices=1,
            max_epochs=2,
            logger=logger,
            default_root_dir=str(Path(os.environ.get("TMPDIR", "/tmp")) / "tmm_gpu_check_lightning"),
            log_every_n_steps=1,
        )
        trainer.fit(module, train_dataloaders=tl._loader(items))
        val = [m for _, m in logger.history if "val/surface_ave" in m]
        train = [m for _, m in logger.history if "train/loss" in m]
        module.model.cpu()
        expected = tl._direct(module.model, items)
        logged = val[-1]
        diffs = {k: abs(float(logged[k]) - v) / max(abs(v), 1e-300) for k, v in expected.items() if k in logged}
        r = {
            "accelerator": trainer.accelerator.__class__.__name__,
            "metric_device": str(module.surface.device) if hasattr(module.surface, "device") else "?",
            "validation_logs": len(val),
            "train_loss_logs": len(train),
            "max_rel_diff_logged_vs_cpu": max(diffs.values()),
            "logged": {k: float(v) for k, v in logged.items()},
        }
        if len(val) != 2 or not train or r["max_rel_diff_logged_vs_cpu"] > 1e-5:
            r["status"] = "failed: logged epoch values missing or off the CPU computation by more than 1e-5"
        return r

    def point_mesh(self) -> dict[str, Any]:
        """Ours at 40k then 630k faces: build + query, query on a kept index; each row written when it is done."""
        dev = self.device
        out = self.live
        out |= {"device": dev, "queries": self.sizes["queries"], "sizes": {}}
        for size, sections in self.sizes["sizes"].items():
            out["sizes"][size] = row = {}
            self._point_row(row, size, sections)
            if dev == "cuda":
                torch.cuda.empty_cache()
        return out

    def _point_row(self, row: dict[str, Any], size: str, sections: tuple[int, int]) -> None:
        from torchmeshmetric import MeshIndex, point_mesh_distance
        from torchmeshmetric.kernels import select

        dev = self.device
        c = point_case(size, sections, self.sizes["queries"])
        v, f, p = c["verts"].to(dev), c["faces"].to(dev), c["points"].to(dev)
        row["faces"] = int(f.shape[0])
        row["auto_backend"] = select.auto_backend_name(torch.device(dev), torch.float32, p.shape[0] * f.shape[0])
        row["ours_build_query"] = timed(lambda: point_mesh_distance(p, v, f), dev, rounds=5)
        self.write()
        index = MeshIndex((v, f))
        index.point_mesh_distance(p[:1000])
        row["ours_query_only"] = timed(lambda: index.point_mesh_distance(p), dev, rounds=5)
        self.write()

    def bruteforce(self) -> dict[str, Any]:
        """The ``torch.compile``d brute force at both sizes against ours (last: a comparison, not a goal)."""
        dev = self.device
        out = self.live
        out |= {"device": dev, "queries": self.sizes["queries"], "compiled": self.compile, "sizes": {}}
        for size, sections in self.sizes["sizes"].items():
            if self.left() < 30:
                out["sizes"][size] = {"status": f"skipped: time budget ({self.left():.0f} s left)"}
                continue
            out["sizes"][size] = row = {}
            self._brute_row(row, size, sections)
            self.write()
            if dev == "cuda":
                torch.cuda.empty_cache()
        return out

    def _brute_row(self, row: dict[str, Any], size: str, sections: tuple[int, int]) -> None:
        from torchmeshmetric import point_mesh_distance

        dev = self.device
        c = point_case(size, sections, self.sizes["queries"])
        v, f, p = c["verts"].to(dev), c["faces"].to(dev), c["points"].to(dev)
        row["faces"] = int(f.shape[0])
        row["ours_build_query"] = timed(lambda: point_mesh_distance(p, v, f), dev, rounds=1)
        ours = point_mesh_distance(p, v, f).dists
        # The (compiled) brute force: timed once on the whole set when its first chunks predict < 20 s (dry run:
        # 10 s) and the budget allows, else projected from them. Each shape compiles once (dynamic=False).
        brute = compiled_bruteforce(v, f, compile=self.compile)
        t0 = time.perf_counter()
        brute(p, max_chunks=2)
        sync(dev)
        row["bruteforce_first_call_s"] = round(time.perf_counter() - t0, 2)
        self.write()
        t0 = time.perf_counter()
        first, done, total = brute(p, max_chunks=4)
        sync(dev)
        per_chunk = (time.perf_counter() - t0) / done
        row["bruteforce_max_abs_diff_vs_ours"] = float((first - ours[: first.shape[0]]).abs().max())
        limit = 10 if self.dry else 20
        if per_chunk * total < limit and self.left() > per_chunk * total + 30:
            row["bruteforce"] = timed(lambda: brute(p), dev, rounds=1, warmup=0)
        else:
            row["bruteforce"] = {"projected_s": per_chunk * total, "from_chunks": done, "of": total}
        bf = row["bruteforce"].get("best_s", row["bruteforce"].get("projected_s"))
        row["ratio_ours_build_query_vs_bruteforce"] = row["ours_build_query"]["best_s"] / bf

    def cpu_threads(self) -> dict[str, Any]:
        from torchmeshmetric import MeshIndex, native

        if native.try_load("bvh") is None:
            return {"status": "failed: the C++ extension 'bvh' does not build here"}
        size, sections = list(self.sizes["sizes"].items())[-1]
        c = point_case(size, sections, self.sizes["queries"])
        v, f, p = c["verts"], c["faces"], c["points"]
        old = torch.get_num_threads()
        r = self.live
        r |= {"faces": int(f.shape[0]), "queries": int(p.shape[0]), "backend": "bvh", "threads": {}}
        try:
            torch.set_num_threads(1)
            t0 = time.perf_counter()
            index = MeshIndex((v, f), backend="bvh")
            index.point_mesh_distance(p[:1000])
            r["build_s_1_thread"] = round(time.perf_counter() - t0, 3)
            for n in self.sizes["threads"]:
                if n > (os.cpu_count() or 1):
                    continue
                torch.set_num_threads(n)
                r["threads"][str(n)] = timed(lambda: index.point_mesh_distance(p), "cpu", rounds=3)
                self.write()
        finally:
            torch.set_num_threads(old)
        one = r["threads"]["1"]["best_s"]
        r["speedup"] = {n: one / t["best_s"] for n, t in r["threads"].items()}
        top = max(r["threads"], key=int)
        r["goal_16_threads_ge_10x"] = r["speedup"][top] >= GOALS["cpu_16_vs_1_thread"] if top == "16" else None
        return r

    # ----------------------------------------------------------------------------------------------- Warp mode

    def warp_point_mesh(self) -> dict[str, Any]:
        from tests.benchmarks.warp_kernels import kernels

        k = kernels()
        wp, query = k.wp, k.query_distance
        dev = self.device

        out = self.live
        out |= {"device": dev, "queries": self.sizes["queries"], "warp": wp.config.version, "sizes": {}}
        for size, sections in self.sizes["sizes"].items():
            out["sizes"][size] = row = {}
            self._warp_row(row, wp, query, size, sections)
            self.write()
        return out

    def _warp_row(self, row: dict[str, Any], wp: Any, query: Any, size: str, sections: tuple[int, int]) -> None:
        from torchmeshmetric import MeshIndex, point_mesh_distance

        dev = self.device
        c = point_case(size, sections, self.sizes["queries"])
        v, f, p = c["verts"].to(dev), c["faces"].to(dev), c["points"].to(dev)
        wv = wp.from_torch(v.contiguous(), dtype=wp.vec3)
        wi = wp.from_torch(f.to(torch.int32).reshape(-1).contiguous(), dtype=wp.int32)
        wpts = wp.from_torch(p.contiguous(), dtype=wp.vec3)
        res = torch.empty(p.shape[0], device=dev)
        wres = wp.from_torch(res)

        def warp_build_query() -> None:
            mesh = wp.Mesh(points=wv, indices=wi)
            wp.launch(query, dim=p.shape[0], inputs=[mesh.id, wpts, wres], device=wpts.device)
            wp.synchronize_device(wpts.device)

        kept = wp.Mesh(points=wv, indices=wi)

        def warp_query() -> None:
            wp.launch(query, dim=p.shape[0], inputs=[kept.id, wpts, wres], device=wpts.device)
            wp.synchronize_device(wpts.device)

        row["faces"] = int(f.shape[0])
        # Build + query first, ours then Warp, written at once: the headline ratio of the issue.
        row["ours_build_query"] = timed(lambda v=v, f=f, p=p: point_mesh_distance(p, v, f), dev, rounds=5)
        free0 = torch.cuda.mem_get_info()[0] if dev == "cuda" else 0
        row["warp_build_query"] = timed(warp_build_query, dev, rounds=5)
        row["ratio_build_query"] = row["ours_build_query"]["best_s"] / row["warp_build_query"]["best_s"]
        row["goal_build_query_le_1.0x_warp"] = row["ratio_build_query"] <= GOALS["build_query_vs_warp"]
        self.write()
        index = MeshIndex((v, f))
        index.point_mesh_distance(p[:1000])
        row["ours_query_only"] = timed(lambda index=index, p=p: index.point_mesh_distance(p), dev, rounds=5)
        row["warp_query_only"] = timed(warp_query, dev, rounds=5)
        if dev == "cuda":
            row["warp_device_mib_held_after"] = (free0 - torch.cuda.mem_get_info()[0]) / 2**20
        row["ratio_query_only"] = row["ours_query_only"]["best_s"] / row["warp_query_only"]["best_s"]
        warp_query()
        ours = index.point_mesh_distance(p).dists
        row["max_abs_diff_ours_vs_warp"] = float((ours - res).abs().max())

    def warp_temporal(self) -> dict[str, Any]:
        from torchmeshmetric.metrics import TemporalConsistencyLoss

        bench = self._bench_module()
        dev = self.device
        state = bench.Step(dev, "registration")
        loss_fn = TemporalConsistencyLoss()
        peer = bench.WarpPeer(dev)

        def ours() -> None:
            state.move()
            a = state.args()
            loss_fn(*a[:4], registration=a[4]).backward()

        def theirs() -> None:
            state.move()
            a = state.args()
            peer.loss(a[0], a[1], a[2], a[4][0]).backward()

        a = state.args()
        value_ours = float(loss_fn(*a[:4], registration=a[4]).detach())
        value_warp = float(peer.loss(a[0], a[1], a[2], a[4][0]).detach())
        r = self.live
        r |= {"pairs": bench.PAIRS, "device": dev, "loss_ours": value_ours, "loss_warp": value_warp}
        self.write()
        r["ours"] = timed(ours, dev, rounds=5, warmup=2)
        self.write()
        r["warp"] = timed(theirs, dev, rounds=5, warmup=2)
        r["ratio"] = r["ours"]["best_s"] / r["warp"]["best_s"]
        r["goal_le_0.5x_warp"] = r["ratio"] <= GOALS["training_step_vs_warp"]
        return r

    # -------------------------------------------------------------------------------------------------- output

    def write(self) -> None:
        doc = {
            "check": self.name,
            "written": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
            "dry_run": self.dry,
            "sections": self.results,
        }
        # Atomically (a temporary file renamed over the old one): a hard stop mid-write leaves the previous version.
        for suffix, text in ((".json", json.dumps(doc, indent=1, default=str)), (".md", markdown(doc))):
            path = self.out / f"{self.name}{suffix}"
            tmp = path.with_name(f".{path.name}.tmp")
            tmp.write_text(text)
            os.replace(tmp, path)


def _fmt(x: Any) -> str:
    if isinstance(x, float):
        return f"{x:.4g}"
    if isinstance(x, dict) and "best_s" in x:
        mem = f", peak {x['peak_mib']:.0f} MiB" if "peak_mib" in x else ""
        return f"{x['best_s'] * 1e3:.2f} ms best of {x['rounds']}{mem}"
    if isinstance(x, dict) and "projected_s" in x:
        return f"~{x['projected_s']:.1f} s projected from {x['from_chunks']} of {x['of']} chunks"
    return str(x)


def markdown(doc: dict[str, Any]) -> str:
    """A short report: one table per section, nested rows flattened (``size / contender``)."""
    lines = [f"# {doc['check']} ({doc['written']})", ""]
    if doc.get("dry_run"):
        lines += ["**Dry run**: small sizes, any device: the code paths, not figures (goal flags do not apply).", ""]
    for name, r in doc["sections"].items():
        lines += [f"## {name}: {r.get('status')}", "", "| what | value |", "|---|---|"]

        def rows(prefix: str, d: dict[str, Any], lines: list[str] = lines) -> None:
            for k, v in d.items():
                if k in ("status", "traceback", "nvidia_smi", "logged"):
                    continue
                if isinstance(v, dict) and ("best_s" in v or "projected_s" in v):
                    lines.append(f"| {prefix}{k} | {_fmt(v).replace('|', '/')} |")
                    timing = {"best_s", "median_s", "rounds", "peak_mib", "projected_s", "from_chunks", "of"}
                    rows(f"{prefix}{k} / ", {kk: vv for kk, vv in v.items() if kk not in timing}, lines)
                elif isinstance(v, dict):
                    rows(f"{prefix}{k} / ", v, lines)
                else:
                    lines.append(f"| {prefix}{k} | {_fmt(v).replace('|', '/')} |")

        rows("", r)
        lines.append("")
    return "\n".join(lines)


BUDGET_S = {"main": 325.0, "warp": 170.0}
"""Default ``--budget`` per mode (docs/benchmarks.md, "GPU check": the device calls' timeout_s are 360 and 210 s)."""


def _hard_stop(signum: int, frame: Any) -> None:
    """SIGTERM and the script's own SIGALRM end the run as SIGINT does (KeyboardInterrupt), keeping what is done."""
    raise KeyboardInterrupt(signal.Signals(signum).name)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mode", choices=["main", "warp"], default="main")
    ap.add_argument("--dry-run", action="store_true", help="small sizes; any device (CUDA-only parts skip on a CPU)")
    ap.add_argument("--out", default=str(ROOT / "out" / "gpu_check"))
    ap.add_argument("--budget", type=float, default=None, help="seconds for the whole run (main 325, warp 170)")
    ap.add_argument("--no-compile", action="store_true", help="eager brute force (no torch.compile)")
    ap.add_argument("--compile", action="store_true", help="torch.compile the brute force in a dry run too")
    ap.add_argument("--only", default="", help="comma-separated section names to run (default: all of the mode)")
    args = ap.parse_args(argv)
    if args.budget is None:
        args.budget = BUDGET_S[args.mode]
    check = Check(args)
    only = {s for s in args.only.split(",") if s}
    # Most valuable first (a hard stop takes the tail): in warp mode the headline ratios; in main mode the
    # compiled kernels' correctness, our point->mesh figures, the training step and the registration, then the CUDA
    # tests (given what is left but ~35 s), the CPU scaling, Lightning, and the compiled brute force (a comparison).
    # need_s: the least time a section is started with (the estimates of docs/benchmarks.md, "GPU check").
    plan: list[tuple[str, Callable[[], Any], bool, float]]
    if args.mode == "main":
        plan = [
            ("environment", check.environment, False, 0),
            ("native_build", check.native_build, False, 20),
            ("triton_compiled", check.triton_compiled, True, 30),
            ("point_mesh", check.point_mesh, False, 15),
            ("temporal_loss", check.temporal_loss, False, 30),
            ("registration", check.registration, False, 20),
            ("cuda_tests", check.cuda_tests, False, 65),
            ("cpu_threads", check.cpu_threads, False, 25),
            ("lightning", check.lightning, False, 20),
            ("bruteforce", check.bruteforce, False, 30),
        ]
    else:
        plan = [
            ("environment", check.environment, False, 0),
            ("native_build", check.native_build, False, 20),
            ("warp_point_mesh", check.warp_point_mesh, False, 20),
            ("warp_temporal", check.warp_temporal, False, 30),
        ]
    # environment and native_build always run (the latter is ~1 s when the extensions are built already).
    plan = [p for p in plan if not only or p[0] in only or p[0] in ("environment", "native_build")]
    signal.signal(signal.SIGTERM, _hard_stop)
    signal.signal(signal.SIGALRM, _hard_stop)
    signal.alarm(max(1, math.ceil(args.budget + 10)))  # the script's own stop, before gpu_check.sh's hard stop
    try:
        for name, fn, needs_cuda, need_s in plan:
            check.section(name, fn, cuda=needs_cuda, need_s=need_s)
    except KeyboardInterrupt as stop:
        signal.alarm(0)
        why = str(stop) or "SIGINT"
        for name, *_ in plan:
            check.results.setdefault(name, {"status": f"not run: hard stop ({why})"})
        check.write()
        print(f"[gpu_check] hard stop ({why}): wrote {check.out / check.name}.json and .md", flush=True)
        return 3
    signal.alarm(0)
    failed = [n for n, r in check.results.items() if str(r.get("status", "")).startswith("failed")]
    print(f"[gpu_check] wrote {check.out / check.name}.json and .md; failed sections: {failed or 'none'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
