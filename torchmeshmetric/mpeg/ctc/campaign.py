"""A whole V-DMC CTC campaign: the CTC chain on every (codec, sequence, condition, rate, frame), cached and shared.

:func:`run_ctc_campaign` plans every frame of a :class:`~torchmeshmetric.mpeg.ctc.manifest.CtcCampaign` (the anchor's
and the test codec's decoded frames against the quantised source), checks every file and every bitstream figure
before any work, and computes the frames :func:`~torchmeshmetric.mpeg.ctc.chain.ctc_frame` has not computed yet:

* **Cache.** Each frame's figures are kept as one JSON file in the cache folder, named by a SHA-256 key of the
  frame's inputs (the bytes of the source and decoded files, their textures and MTLs) and of the chain's settings
  (bit depths, box, PSNR peak, grid and IBSM settings, :data:`CTC_RESULTS_VERSION`). A rerun after an interruption
  computes only the frames without a file; a second test codec against the same anchor finds the anchor's frames;
  equal inputs anywhere in the campaign are computed once. Each record holds the SHA-256 checksum of its content,
  checked with what it must hold when it is read; a record failing a check is computed again, after a warning.
* **Processes.** Under ``torchrun`` the files are hashed and the missing frames computed round robin by the ranks
  (:func:`~torchmeshmetric.tasks.run_tasks`); rank 0 reads the cache and returns the result, the others ``None``.

The result holds each codec's rows of the test model's CSV (:class:`~torchmeshmetric.mpeg.ctc.sheet.RatePoint`:
sequence means as mmetric prints them, bits, runtimes and memory from the codec's CSV, files and manifest points),
from which :func:`~torchmeshmetric.mpeg.ctc.sheet.ctc_summary` computes the CTC sheet's summary.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

from torchmeshmetric._atomic import atomic_write
from torchmeshmetric._checksum import content_sha256
from torchmeshmetric._format import json_safe
from torchmeshmetric.data.obj import obj_mtllibs, parse_mtl
from torchmeshmetric.mpeg.ctc.frame_pattern import frame_path
from torchmeshmetric.mpeg.ctc.manifest import CtcCampaign, CtcCampaignSequence, CtcCodec, codec_path
from torchmeshmetric.mpeg.ctc.sheet import COMPONENTS, RatePoint, SheetCondition, SheetSequence, read_test_model_csv

__all__ = ["CTC_RESULTS_VERSION", "CampaignResult", "FrameTask", "frame_rows_csv", "plan_frames", "run_ctc_campaign"]

_COLUMNS = ("GridD1", "GridD2", "GridLuma", "GridChromaCb", "GridChromaCr", "IbsmGeom", "IbsmLuma")
_CODECS = ("anchor", "test")


class FrameTask(NamedTuple):
    """One frame of one codec's point: its files and its place in the campaign.

    Attributes:
        codec: ``"anchor"`` or ``"test"``.
        seq: the sequence.
        cond_id, rate_id, frame: the point and the frame number.
        ref, ref_texture: the quantised source frame and its texture (``None``: the MTL's).
        dis, dis_texture: the decoded frame and its texture.
        decoded_qt: the decoded frame's UV bit depth.
    """

    codec: str
    seq: CtcCampaignSequence
    cond_id: int
    rate_id: int
    frame: int
    ref: str
    ref_texture: str | None
    dis: str
    dis_texture: str | None
    decoded_qt: int

    def describe(self) -> str:
        """The task's name in messages."""
        return (
            f"{self.codec} sequence {self.seq.name!r} condition {self.cond_id} rate {self.rate_id} frame {self.frame}"
        )


@dataclass(frozen=True)
class CampaignResult:
    """What a campaign computed (rank 0).

    Attributes:
        points: codec (``"anchor"``, ``"test"``) -> ``(seq_id, cond_id, rate_id)`` -> its row of the test model's CSV.
        sequences: the sheet's view of the sequences (input faces counted when not given).
        conditions: the sheet's conditions.
        frames: one record per planned frame, in plan order: the task's place (``codec``, ``sequence``,
            ``condition``, ``rate``, ``frame``) and ``figures`` (column -> PSNR, ``inf`` for identical frames).
        computed: frames computed by this run.
        from_cache: frames read from the cache (the others have the same inputs and settings as a frame computed
            or read: the campaign's frames less these two counts).
        chain_seconds: the wall seconds of the frames computed by this run, summed (each frame's read and chain).
        names: the two codecs' names.

    Example:
        >>> import os, tempfile
        >>> from torchmeshmetric.mpeg import load_ctc_campaign
        >>> tetrahedron = ["v 0 0 0", "v 1023 0 0", "v 0 1023 0", "v 0 0 511",
        ...                "f 1 3 2", "f 1 2 4", "f 1 4 3", "f 2 3 4"]
        >>> manifest = ["[options]", 'cache_dir = ""', "grid_size = 64", "ibsm_resolution = 0", "[[sequences]]",
        ...             'name = "tet"', "id = 1", 'source = "src_%04d.obj"', "first_frame = 0", "frame_count = 1",
        ...             "fps = 30", "qp = 10", "qt = 0", "min_pos = [0, 0, 0]", "max_pos = [1023, 1023, 511]",
        ...             "[[conditions]]", "id = 1", "rates = [1]"]
        >>> for codec in ("anchor", "test"):  # both "decode" the source losslessly, 8000 bits
        ...     manifest += [f"[{codec}]", 'decoded = "src_%04d.obj"', f"[[{codec}.points]]", 'sequence = "tet"',
        ...                  "condition = 1", "rate = 1", "total_bits = 8000"]
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     for name, lines in (("src_0000.obj", tetrahedron), ("campaign.toml", manifest)):
        ...         with open(os.path.join(folder, name), "w") as f:
        ...             _ = f.write(chr(10).join(lines) + chr(10))
        ...     result = run_ctc_campaign(load_ctc_campaign(os.path.join(folder, "campaign.toml")))
        >>> point = result.points["test"].get((1, 1, 1))  # (seq_id, cond_id, rate_id)
        >>> point.total_bits, point.figures, result.names
        (8000.0, {'GridD1': 99.99, 'GridD2': 99.99}, ('anchor', 'test'))
    """

    points: dict[str, dict[tuple[int, int, int], RatePoint]]
    sequences: list[SheetSequence]
    conditions: list[SheetCondition]
    frames: list[dict[str, Any]]
    computed: int
    from_cache: int
    chain_seconds: float
    names: tuple[str, str]


def plan_frames(campaign: CtcCampaign) -> list[FrameTask]:
    """Every frame of the campaign (anchor first, then test; sequences, conditions, rates, frames in manifest order).

    Raises:
        ValueError: a frame file or texture is missing, a directory or empty (naming the task and the file).
    """
    tasks = []
    for name in _CODECS:
        codec: CtcCodec = getattr(campaign, name)
        for seq in campaign.sequences:
            for cond in campaign.conditions:
                for rate in cond.rates:
                    dec = codec_path(codec.decoded, seq, cond.cond_id, rate)
                    tex = (
                        None
                        if codec.decoded_texture is None
                        else codec_path(codec.decoded_texture, seq, cond.cond_id, rate)
                    )
                    for k in seq.frames:
                        files = (
                            frame_path(seq.source, k),
                            None if seq.source_texture is None else frame_path(seq.source_texture, k),
                            frame_path(dec, k),
                            None if tex is None else frame_path(tex, k),
                        )
                        task = FrameTask(
                            name, seq, cond.cond_id, rate, k, *files[:2], files[2], files[3], codec.decoded_qt
                        )
                        for f in files:
                            if f is not None:
                                _check_file(f, task)
                        tasks.append(task)
    return tasks


def _check_file(path: str, task: FrameTask) -> None:
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{task.describe()}: {path!r} is a directory, expected a file")
    if not p.is_file():
        raise ValueError(f"{task.describe()}: file {path!r} not found")
    if p.stat().st_size == 0:
        raise ValueError(f"{task.describe()}: file {path!r} is empty")


def _digest(item: tuple[str, bool]) -> str:
    """SHA-256 of a file; for an OBJ whose texture comes from its MTL, of the MTL and its ``map_Kd`` files too."""
    path, with_materials = item
    p = Path(path)
    h = hashlib.sha256()
    data = p.read_bytes()
    h.update(data)
    if with_materials and p.suffix.lower() == ".obj":
        # the reader's own rule for what an mtllib statement names: a regex of the line took a trailing comment as
        # part of the name, and the MTL and its texture were left out of the key (stale figures, review R #1)
        for name in obj_mtllibs(data):
            mtl = p.parent / name
            if mtl.is_file():
                h.update(b"\0mtl\0" + mtl.read_bytes())
                # the package's MTL reader: a texture name may hold spaces, after options (-s 1 1 1 my tex.png);
                # the last word alone left such a texture out of the key, and a changed one reused stale figures
                for material in parse_mtl(mtl):
                    tex = None if material.map_kd is None else mtl.parent / material.map_kd
                    if tex is not None and tex.is_file():
                        h.update(b"\0map\0" + tex.read_bytes())
    return h.hexdigest()


#: The revision of a frame's CTC figures, part of each frame's cache key. Raise it in every change that changes a
#: figure the chain computes (sampling, PSNR, IBSM, reading the files) without changing a setting in the key: records
#: of the earlier revisions then miss and are computed again (docs/architecture.md, "Where to add ..."). The key held
#: the package's version instead, which stayed 0.1.0 through such changes. 1: the first revision (review I, 2026-12).
CTC_RESULTS_VERSION = 1


def _settings(campaign: CtcCampaign, task: FrameTask) -> dict[str, Any]:
    s = task.seq
    return {
        "qp": s.qp,
        "qt": s.qt,
        "decoded_qt": task.decoded_qt,
        "min_pos": list(s.min_pos),
        "max_pos": list(s.max_pos),
        "resolution": s.resolution,
        "grid_size": campaign.grid_size,
        "ibsm_resolution": campaign.ibsm_resolution,
        "ibsm_cameras": campaign.ibsm_cameras,
        "results_version": CTC_RESULTS_VERSION,
    }


def _key(campaign: CtcCampaign, task: FrameTask, digests: dict[tuple[str, bool], str]) -> str:
    inputs = {
        "ref": digests[task.ref, task.ref_texture is None],
        "ref_texture": None if task.ref_texture is None else digests[task.ref_texture, False],
        "dis": digests[task.dis, task.dis_texture is None],
        "dis_texture": None if task.dis_texture is None else digests[task.dis_texture, False],
        **_settings(campaign, task),
    }
    return hashlib.sha256(json.dumps(inputs, sort_keys=True).encode()).hexdigest()


def _cache_file(folder: Path, key: str) -> Path:
    return folder / key[:2] / f"{key}.json"


def _cached_figure(value: Any) -> float | None:
    """A figure of a cache record: a finite number, or ``"inf"`` (identical frames, as json_safe writes it)."""
    if value == "inf":
        return math.inf
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value)


def _cached_count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


#: The colour figures: the chain computes the three or none (both frames carry colour, or not).
_COLOUR = frozenset(("GridLuma", "GridChromaCb", "GridChromaCr"))


def _record_problem(record: Any, key: str, ibsm: bool) -> str | None:
    """What is wrong with a record read from the cache for ``key`` (its checksum removed), or ``None``.

    The cache folder may be shared by several machines: a record that holds a figure that is not a finite number or
    ``"inf"`` (``NaN``, a string), a point or face count that is not a count, or not the figures its settings compute
    (GridD1 and GridD2; IbsmGeom and IbsmLuma exactly when IBSM is on; the three colour figures or none) is damaged:
    one without a figure made a point's mean fail with an error about textures, or left its column blank.
    """
    if not isinstance(record, dict):
        return f"expected a JSON object, found {type(record).__name__}"
    if record.get("key") != key:
        return f"it holds the record of the key {record.get('key')!r}, not of its file name"
    if not isinstance(record.get("figures"), dict):
        return f"figures={record.get('figures')!r}: expected a JSON object of figures"
    figures = {k: _cached_figure(v) for k, v in record["figures"].items()}
    bad = [f"{k}={record['figures'][k]!r}" for k, v in figures.items() if v is None or k not in _COLUMNS]
    bad += [
        f"{k}={record.get(k)!r}"
        for k in ("points_ref", "points_dis", "faces_ref", "faces_dis")
        if not _cached_count(record.get(k))
    ]
    if bad:
        return f"{', '.join(bad)}: expected finite numbers or 'inf', and counts"
    needed = {"GridD1", "GridD2"} | ({"IbsmGeom", "IbsmLuma"} if ibsm else set())
    if _COLOUR & set(figures):
        needed |= _COLOUR
    missing = [c for c in _COLUMNS if c in needed and c not in figures]
    if missing:
        computes = ", ".join(c for c in _COLUMNS if c in needed)
        return f"no {', '.join(missing)}: the campaign's settings compute {computes}"
    extra = [c for c in ("IbsmGeom", "IbsmLuma") if c in figures and not ibsm]
    if extra:
        return f"{', '.join(extra)} present, but the campaign computes no IBSM"
    return None


class _Unchecked(NamedTuple):
    """A record without a checksum (written before records had one)."""

    path: Path


def _read_cached(folder: Path, key: str, *, ibsm: bool) -> dict[str, Any] | str | _Unchecked | None:
    """A frame's cached record; ``None`` when absent, else why it is not used (then it is computed again).

    A record is used only when it parses, its content matches the SHA-256 checksum it holds (``"sha256"``, as the
    registration cache's entries: a truncated copy, a zeroed block or a hand edit of a shared folder's record would
    reach the CSVs and the summary) and it holds what its settings compute (:func:`_record_problem`).

    Returns:
        The record (its figures as floats), ``None`` (no record), a string (why the record is damaged) or
        :class:`_Unchecked` (a record without a checksum).
    """
    path = _cache_file(folder, key)
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    try:
        record = json.loads(text)
    except ValueError as exc:  # UnicodeDecodeError is one: a zero-byte, truncated or overwritten file
        return f"not JSON ({'an empty file' if not text else exc})"
    if isinstance(record, dict):
        stored = record.pop("sha256", None)
        if stored is None:
            return _Unchecked(path)
        if stored != content_sha256(record):
            return "its content does not match its checksum (sha256)"
    problem = _record_problem(record, key, ibsm)
    if problem is not None:
        return problem
    record["figures"] = {k: _cached_figure(v) for k, v in record["figures"].items()}
    return record


def _read_records(folder: Path, keys: list[str], ibsm: bool) -> dict[str, dict[str, Any]]:
    """The usable records of ``keys``; a warning names each damaged one, and one the records without a checksum."""
    records: dict[str, dict[str, Any]] = {}
    unchecked: list[Path] = []
    for key in keys:
        found = _read_cached(folder, key, ibsm=ibsm)
        if isinstance(found, dict):
            records[key] = found
        elif isinstance(found, _Unchecked):
            unchecked.append(found.path)
        elif found is not None:
            warnings.warn(
                f"{_cache_file(folder, key)}: damaged cache record ({found}); not used, the frame is computed again",
                UserWarning,
                stacklevel=3,
            )
    if unchecked:  # one line for all: a whole cache written by the earlier release would give one per frame
        n = len(unchecked)
        warnings.warn(
            f"{n} cache record{'s' if n > 1 else ''} in {folder} hold{'' if n > 1 else 's'} no checksum (sha256; "
            f"written before records had one), first {unchecked[0]}: not used, "
            f"{'their frames are' if n > 1 else 'its frame is'} computed again and the records replaced",
            UserWarning,
            stacklevel=3,
        )
    return records


def _load(item: tuple[str, FrameTask]) -> tuple[Any, Any, float]:
    """A frame's source and decoded meshes and the seconds reading took (run ahead in a background thread)."""
    from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh

    task = item[1]
    t0 = time.perf_counter()
    try:
        return (
            load_textured_mesh(task.ref, task.ref_texture),
            load_textured_mesh(task.dis, task.dis_texture),
            (time.perf_counter() - t0),
        )
    except ValueError as exc:
        # the task is named once, by run_tasks' note ("... (while running <task>)"): prefixed here too, it was said
        # twice; the reader's "path: " (its argument's name) means nothing to the command's user (review R #10)
        exc.args = (str(exc).removeprefix("path: "), *exc.args[1:])
        raise


class _RecordFolder:
    """The cache folder as the campaign writes it: each frame's record at once, atomically, as it is computed.

    A record that cannot be written (a read-only folder: a shared archive of records; a full disk; a folder standing
    at its path) failed the campaign at the first frame it computed, naming a subfolder; then, one such record turned
    storing off for the rest of the run (review R #8: a rerun computed every later frame again). Each record is now
    tried, and each distinct cause gives one warning naming the folder and the first record it stopped.
    """

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self.causes: set[str] = set()
        self.not_stored = 0

    def write(self, key: str, record: dict[str, Any]) -> None:
        """Keep ``record`` (checksummed, :func:`_record_text`) as ``key``'s file (nothing without a folder)."""
        if self.path is None:
            return
        file = _cache_file(self.path, key)
        try:
            file.parent.mkdir(parents=True, exist_ok=True)
            atomic_write(file, _record_text(record), overwrite=True, join_file_set=False)
        except OSError as exc:
            self.not_stored += 1
            cause = exc.strerror or type(exc).__name__
            if cause in self.causes:
                return
            self.causes.add(cause)
            why = f"{exc.strerror}: {file}" if exc.strerror else str(exc).removeprefix("path: ")
            warnings.warn(
                f"cannot store frame records in the cache folder {self.path} ({why}); the campaign goes on and "
                "stores the records it can (the frames not stored are computed again by a rerun; the records "
                "already there are still read)",
                UserWarning,
                stacklevel=3,
            )


def _record_text(record: dict[str, Any]) -> str:
    """A record as its cache file holds it: JSON, with the SHA-256 checksum of its content (``"sha256"``)."""
    content = json.loads(json.dumps(json_safe(record)))  # the checksum of what a reader parses, exactly
    return json.dumps({**content, "sha256": content_sha256(content)}, indent=1) + "\n"


def _compute(
    campaign: CtcCampaign, task: FrameTask, key: str, records: _RecordFolder, loaded: tuple[Any, Any, float]
) -> dict[str, Any]:
    """One frame through the chain; its record written to the cache at once (atomically)."""
    from torchmeshmetric._version import __version__
    from torchmeshmetric.mpeg.ctc.chain import ctc_frame
    from torchmeshmetric.mpeg.sampling.grid_sampling import GridTooLargeError

    ref, dis, read_seconds = loaded
    t0 = time.perf_counter() - read_seconds  # the frame's seconds: its reading (ahead of time) and its chain
    try:
        f = ctc_frame(ref, dis, campaign.settings(task.seq, task.decoded_qt), frame=task.frame)
    except GridTooLargeError as exc:  # it named --grid-size, an option this command does not have (review R #10)
        head, _, rest = str(exc).partition(": ")
        raise GridTooLargeError(
            f"CTC campaign manifest {str(campaign.path)!r}: [options] grid_size {campaign.grid_size}: {rest}"
            if head.startswith("grid_size (--grid-size)")
            else str(exc)
        ) from exc
    record = {
        "key": key,
        "figures": dict(f.figures),
        "points_ref": f.points_ref,
        "points_dis": f.points_dis,
        "faces_ref": int(ref.mesh.faces.shape[0]),
        "faces_dis": int(dis.mesh.faces.shape[0]),
        "seconds": time.perf_counter() - t0,
        "stages": f.seconds,
        "inputs": {"ref": task.ref, "ref_texture": task.ref_texture, "dis": task.dis, "dis_texture": task.dis_texture},
        "settings": _settings(campaign, task),
        "library_version": __version__,  # which package computed it (provenance; the key holds the results version)
    }
    records.write(key, record)
    return record


def _log_value(path: str, label: str, what: str) -> float | None:
    """The 4th field of the log's line holding ``label`` (what ``collect_results.sh`` greps with awk)."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{what}: log {path!r} not found")
    for n, line in enumerate(p.read_text(errors="replace").splitlines(), start=1):
        if label in line:
            fields = line.split()
            try:
                return float(fields[3])
            except (IndexError, ValueError):
                raise ValueError(f"{path}:{n}: expected a number as the 4th field of {line.strip()!r}") from None
    return None


def _codec_values(
    codec: CtcCodec, seq: CtcCampaignSequence, cond_id: int, rate_id: int, rows: dict[tuple[int, int, int], RatePoint]
) -> dict[str, Any]:
    """Bits, faces, runtimes, memory and components of one point: the CSV's, then the files', then the manifest's."""
    key = (seq.seq_id, cond_id, rate_id)
    what = f"{codec.name}: sequence {seq.name!r} condition {cond_id} rate {rate_id}"
    v: dict[str, Any] = {}
    row = rows.get(key)
    if row is not None:
        v.update(
            {
                k: getattr(row, k)
                for k in (
                    "total_bits",
                    "output_faces",
                    "encoder_seconds",
                    "decoder_seconds",
                    "encoder_memory",
                    "decoder_memory",
                )
            }
        )
        v = {k: x for k, x in v.items() if x is not None and not (isinstance(x, float) and math.isnan(x))}
    if codec.bitstream is not None:
        bits = Path(codec_path(codec.bitstream, seq, cond_id, rate_id))
        if not bits.is_file():
            raise ValueError(f"{what}: bitstream {str(bits)!r} not found")
        v["total_bits"] = bits.stat().st_size * 8
        if v["total_bits"] == 0:  # an empty file is a failed encode, not a point at 0 bits
            raise ValueError(f"{what}: bitstream {str(bits)!r} is empty (0 bytes)")
    for log, side in ((codec.encoder_log, "encoder"), (codec.decoder_log, "decoder")):
        if log is None:
            continue
        path = codec_path(log, seq, cond_id, rate_id)
        found = {
            f"{side}_seconds": _log_value(path, "Sequence processing time", what),
            f"{side}_memory": _log_value(path, "Sequence peak memory", what),
        }
        if side == "encoder":
            found["output_faces"] = _log_value(path, "Sequence face count", what)
        memory = found[f"{side}_memory"]
        if memory is not None:
            found[f"{side}_memory"] = memory / 1024.0  # KB -> MB, as the script
        v.update({k: x for k, x in found.items() if x is not None})
    v.update(codec.points.get(key, {}))
    if "total_bits" not in v:
        raise ValueError(
            f"{what}: no bitstream size (give the codec's 'csv', its 'bitstream' files, or "
            "'total_bits' in its [[points]])"
        )
    return v


def _mm_printed(x: float) -> float:
    """The value as mmetric prints it (9 significant digits), which the test model's CSV holds."""
    return x if math.isinf(x) else float(format(x, ".9g"))


def _point(
    task_frames: list[dict[str, Any]], values: dict[str, Any], key: tuple[int, int, int], lossless: bool, what: str
) -> RatePoint:
    """One CSV row: each metric's mmetric mean over the point's frames.

    A lossless point whose frames all sample exactly as their sources (every grid figure infinite) gets ``inf`` in
    every column, as ``collect_results.sh`` writes when mmetric finds the meshes and textures equal.
    """
    from torchmeshmetric.mpeg.ctc.chain import ctc_mean

    grid = [v for f in task_frames for c, v in f["figures"].items() if c.startswith("Grid")]
    identical = lossless and bool(grid) and all(math.isinf(v) and v > 0 for v in grid)
    figures = {}
    for c in _COLUMNS:
        vals = [f["figures"][c] for f in task_frames if c in f["figures"]]
        if vals and len(vals) != len(task_frames):
            raise ValueError(
                f"{what}: {c} is computed on {len(vals)} of {len(task_frames)} frames (colour or "
                "texture missing on some frames); the sequence mean needs every frame"
            )
        if vals:
            figures[c] = math.inf if identical else _mm_printed(ctc_mean(vals))
    faces = values.get("output_faces")
    return RatePoint(
        *key,
        total_bits=float(values["total_bits"]),
        figures=figures,
        output_faces=int(faces) if faces is not None else sum(f["faces_dis"] for f in task_frames),
        encoder_seconds=values.get("encoder_seconds"),
        decoder_seconds=values.get("decoder_seconds"),
        encoder_memory=values.get("encoder_memory"),
        decoder_memory=values.get("decoder_memory"),
        components={c: float(x) for c, x in values.get("components", {}).items() if c in COMPONENTS},
    )


def _codec_rows(campaign: CtcCampaign, name: str) -> dict[tuple[int, int, int], RatePoint]:
    """The rows of a codec's test-model CSV (none without one); a missing file named by the manifest and its key.

    ``nope.csv: file not found`` named neither (review R #10), where every other manifest error does.
    """
    csv_path = getattr(campaign, name).csv
    if csv_path is None:
        return {}
    if not csv_path.is_file():
        what = "is a directory, expected a file" if csv_path.is_dir() else "not found"
        raise ValueError(f"CTC campaign manifest {str(campaign.path)!r}: [{name}] 'csv': {str(csv_path)!r} {what}")
    return read_test_model_csv(csv_path)


def run_ctc_campaign(
    campaign: CtcCampaign,
    *,
    cache_dir: Path | None = None,
    progress: Callable[[FrameTask, dict[str, Any]], None] | None = None,
    tasks: list[FrameTask] | None = None,
) -> CampaignResult | None:
    """Run a campaign (see the module): every frame not cached yet, then every codec's CSV rows.

    Every rank of a torchrun job must call it (a collective); the frames are shared by the ranks.

    Args:
        campaign: the parsed manifest (:func:`~torchmeshmetric.mpeg.ctc.manifest.load_ctc_campaign`).
        cache_dir: the per-frame cache folder (default the manifest's ``cache_dir``; ``None`` in both: no cache,
            every frame computed). A record that fails its checks (:func:`_read_cached`) is computed again after a
            warning naming it. One that cannot be written (read-only) is read; the records that cannot be stored
            are skipped, after one warning per cause.
        progress: called with each frame computed here, and its record (on the rank that computed it).
        tasks: ``plan_frames(campaign)``, when the caller planned the frames already (its files then checked).

    Returns:
        :class:`CampaignResult` on rank 0, ``None`` on the others.

    Raises:
        ValueError: a missing or empty frame file, a point without a bitstream size, a CSV or log that cannot be
            read, a metric present on some frames of a point only; all but the last found before any frame is
            computed.
        RankFailedError: under torchrun, a frame failed on some rank (naming the rank and the frame).

    Example:
        >>> import os, tempfile
        >>> from torchmeshmetric.mpeg import load_ctc_campaign
        >>> tetrahedron = ["v 0 0 0", "v 1023 0 0", "v 0 1023 0", "v 0 0 511",
        ...                "f 1 3 2", "f 1 2 4", "f 1 4 3", "f 2 3 4"]
        >>> manifest = ["[options]", 'cache_dir = ""', "grid_size = 64", "ibsm_resolution = 0", "[[sequences]]",
        ...             'name = "tet"', "id = 1", 'source = "src_%04d.obj"', "first_frame = 0", "frame_count = 1",
        ...             "fps = 30", "qp = 10", "qt = 0", "min_pos = [0, 0, 0]", "max_pos = [1023, 1023, 511]",
        ...             "[[conditions]]", "id = 1", "rates = [1]"]
        >>> for codec in ("anchor", "test"):  # both "decode" the source losslessly, 8000 bits
        ...     manifest += [f"[{codec}]", 'decoded = "src_%04d.obj"', f"[[{codec}.points]]", 'sequence = "tet"',
        ...                  "condition = 1", "rate = 1", "total_bits = 8000"]
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     for name, lines in (("src_0000.obj", tetrahedron), ("campaign.toml", manifest)):
        ...         with open(os.path.join(folder, name), "w") as f:
        ...             _ = f.write(chr(10).join(lines) + chr(10))
        ...     result = run_ctc_campaign(load_ctc_campaign(os.path.join(folder, "campaign.toml")))
        >>> result.computed, result.from_cache, [f["figures"] for f in result.frames]  # equal inputs: computed once
        (1, 0, [{'GridD1': inf, 'GridD2': inf}, {'GridD1': inf, 'GridD2': inf}])
    """
    from torchmeshmetric.tasks import exchange, rank_and_world_size, run_tasks, shard

    rank, world = rank_and_world_size()
    folder = cache_dir if cache_dir is not None else campaign.cache_dir
    if tasks is None:
        tasks = plan_frames(campaign)
    rows = {name: _codec_rows(campaign, name) for name in _CODECS}
    values = {
        (name, s.seq_id, c.cond_id, r): _codec_values(getattr(campaign, name), s, c.cond_id, r, rows[name])
        for name in _CODECS
        for s in campaign.sequences
        for c in campaign.conditions
        for r in c.rates
    }
    files = sorted(
        {(t.ref, t.ref_texture is None) for t in tasks}
        | {(t.dis, t.dis_texture is None) for t in tasks}
        | {(x, False) for t in tasks for x in (t.ref_texture, t.dis_texture) if x is not None}
    )
    hashed = run_tasks(_digest, files, describe=lambda f: f"hashing {f[0]!r}", to=None)
    assert hashed is not None
    digests = dict(zip(files, hashed, strict=True))
    keys = [_key(campaign, t, digests) for t in tasks]
    unique: dict[str, FrameTask] = {}
    for k, t in zip(keys, tasks, strict=True):
        unique.setdefault(k, t)
    cached: dict[str, dict[str, Any]] = {}
    if rank == 0 and folder is not None:
        cached = _read_records(folder, list(unique), campaign.ibsm_resolution is not None)
    done = set(exchange(sorted(cached) if rank == 0 else None, what="the list of cached frames")[0])
    missing = [(k, t) for k, t in unique.items() if k not in done]

    from torchmeshmetric.data.sequence import Prefetcher

    # the next frame is read in a background thread while this one is computed (run_tasks takes this rank's tasks
    # in the prefetcher's order, as the ctc command)
    ahead = Prefetcher([missing[i] for i in shard(len(missing), rank, world)], load=_load, ahead=1)
    stored = _RecordFolder(folder)

    def one(item: tuple[str, FrameTask]) -> dict[str, Any]:
        record = _compute(campaign, item[1], item[0], stored, next(ahead))
        if progress is not None:
            progress(item[1], record)
        return record

    with ahead:
        computed = run_tasks(one, missing, describe=lambda item: item[1].describe(), to=0)
    if rank != 0 or computed is None:
        return None
    records = {**cached, **{k: r for (k, _), r in zip(missing, computed, strict=True)}}
    return _result(campaign, tasks, keys, records, values, computed, len(cached))


def _result(
    campaign: CtcCampaign,
    tasks: list[FrameTask],
    keys: list[str],
    records: dict[str, dict[str, Any]],
    values: dict[tuple[str, int, int, int], dict[str, Any]],
    computed: list[dict[str, Any]],
    from_cache: int,
) -> CampaignResult:
    frames: list[dict[str, Any]] = []
    by_point: dict[tuple[str, int, int, int], list[dict[str, Any]]] = {}
    input_faces: dict[int, dict[int, int]] = {}
    for t, k in zip(tasks, keys, strict=True):
        r = records[k]
        frames.append(
            {
                "codec": t.codec,
                "sequence": t.seq.name,
                "condition": t.cond_id,
                "rate": t.rate_id,
                "frame": t.frame,
                "figures": r["figures"],
                "points_ref": r["points_ref"],
                "points_dis": r["points_dis"],
            }
        )
        by_point.setdefault((t.codec, t.seq.seq_id, t.cond_id, t.rate_id), []).append(r)
        input_faces.setdefault(t.seq.seq_id, {})[t.frame] = r["faces_ref"]
    lossless = {c.cond_id: c.lossless for c in campaign.conditions}
    points: dict[str, dict[tuple[int, int, int], RatePoint]] = {name: {} for name in _CODECS}
    for (codec, seq_id, cond_id, rate_id), recs in by_point.items():
        what = f"{codec} sequence {seq_id} condition {cond_id} rate {rate_id}"
        key = (seq_id, cond_id, rate_id)
        points[codec][key] = _point(recs, values[(codec, *key)], key, lossless[cond_id], what)
    sequences = [
        SheetSequence(
            s.seq_id, s.name, s.cls, s.frame_count, s.fps, s.input_faces or sum(input_faces[s.seq_id].values())
        )
        for s in campaign.sequences
    ]
    conditions = [SheetCondition(c.cond_id, c.name, c.lossless) for c in campaign.conditions]
    return CampaignResult(
        points,
        sequences,
        conditions,
        frames,
        len(computed),
        from_cache,
        math.fsum(r["seconds"] for r in computed),
        (campaign.anchor.name, campaign.test.name),
    )


def frame_rows_csv(frames: list[dict[str, Any]]) -> str:
    """Every frame's figures as CSV: ``codec, sequence, condition, rate, frame``, the CTC columns (full precision)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["codec", "sequence", "condition", "rate", "frame", *_COLUMNS, "points_ref", "points_dis"])
    for f in frames:
        figs = ["" if c not in f["figures"] else repr(float(f["figures"][c])) for c in _COLUMNS]
        w.writerow(
            [f["codec"], f["sequence"], f["condition"], f["rate"], f["frame"], *figs, f["points_ref"], f["points_dis"]]
        )
    return buf.getvalue()
