"""The manifest of a V-DMC CTC campaign (TOML): sequences, conditions and rates, a test codec and an anchor.

Example (``examples/ctc_campaign.toml`` is a complete one)::

    [options]                       # all optional; these are the defaults
    cache_dir = "ctc-cache"         # per-frame results, relative to the manifest (a rerun resumes from it); "": none
    grid_size = 1024                # sample --gridSize
    ibsm_resolution = 2048          # 0: no IBSM
    ibsm_cameras = 16

    [[sequences]]
    name = "longdress"
    id = 1                          # SeqId of the test model's CSV
    class = "cat1-A"
    source = "src/longdress_fr%04d_qp10_qt12.obj"      # quantised source frames (printf frame field)
    source_texture = "src/longdress_fr%04d.png"        # optional (default: the OBJ's MTL)
    first_frame = 1051
    frame_count = 32
    fps = 30
    qp = 10
    qt = 12
    min_pos = [-1, -1, -1]          # the sequence's box (the test model's mmetric.cfg minPosition/maxPosition)
    max_pos = [1023, 1023, 1023]
    # resolution = 1024             # PSNR peak; default the box's longest side
    # input_faces = 11997440        # the sheet's "№ input faces"; default counted from the source frames

    [[conditions]]
    id = 1
    name = "C1 lossy AI"
    rates = [1, 2, 3, 4, 5]
    # lossless = false

    [anchor]                        # and [test]: the same keys
    name = "anchor"
    decoded = "anchor/s{seq_id}c{cond_id}r{rate_id}_{sequence}/dec_%04d.obj"
    decoded_texture = "anchor/s{seq_id}c{cond_id}r{rate_id}_{sequence}/dec_%04d.png"   # optional
    csv = "anchor.csv"              # optional: the CSV the test model's scripts wrote (bits, runtimes, memory)
    # bitstream = "anchor/s{seq_id}c{cond_id}r{rate_id}_{sequence}/out.vmesh"   # bits = its size * 8
    # encoder_log = ".../encoder.log"   decoder_log = ".../decoder.log"           # as collect_results.sh reads them
    # decoded_qt = 0

    [[anchor.points]]               # optional, per (sequence, condition, rate); overrides the CSV and the files
    sequence = "longdress"
    condition = 1
    rate = 1
    total_bits = 1234567
    components = { mesh_intra = 1000, mesh_inter = 0, displacements = 2000, texture = 3000, metadata = 10 }
    encoder_seconds = 12.5
    decoder_seconds = 1.5

Paths are relative to the manifest; ``{sequence}``, ``{seq_id}``, ``{cond_id}``, ``{rate_id}`` name the point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from torchmeshmetric._toml import kind_name, read_manifest
from torchmeshmetric.mpeg.ctc.box import check_box
from torchmeshmetric.mpeg.ctc.frame_pattern import frame_path
from torchmeshmetric.mpeg.ctc.settings import CtcSettings, box_longest_side

__all__ = [
    "CtcCampaign",
    "CtcCampaignSequence",
    "CtcCodec",
    "CtcCondition",
    "DEFAULT_CACHE_DIR",
    "CtcManifestError",
    "codec_path",
    "load_ctc_campaign",
]

_COMPONENTS = ("mesh_intra", "mesh_inter", "displacements", "texture", "metadata")
_POINT_NUMBERS = (
    "total_bits",
    "output_faces",
    "encoder_seconds",
    "decoder_seconds",
    "encoder_memory",
    "decoder_memory",
)


#: The per-frame cache folder of a manifest without ``cache_dir`` (relative to the manifest, as its other paths).
DEFAULT_CACHE_DIR = "ctc-cache"


class CtcManifestError(ValueError):
    """A CTC campaign manifest that cannot be read or used; names the file and the key.

    Example:
        >>> import os, tempfile
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     path = os.path.join(folder, "c.toml")
        ...     with open(path, "w") as f:
        ...         _ = f.write("[[sequences]]" + chr(10) + "name = 1" + chr(10))
        ...     try:
        ...         load_ctc_campaign(path)
        ...     except CtcManifestError as error:  # a ValueError too
        ...         print(str(error).split(": ", 1)[1])
        sequences[0]: 'name' must be a string, found 1
    """


@dataclass(frozen=True)
class CtcCampaignSequence:
    """One sequence of the campaign (see the module for the keys).

    Attributes:
        name, seq_id, cls: its name, ``SeqId`` and class.
        source: printf pattern of the quantised source frames (absolute or relative to the working folder; a
            ``%`` of the manifest's folder written ``%%``).
        source_texture: pattern of their textures, or ``None`` (the OBJ's MTL).
        first_frame, frame_count: the frames measured.
        fps: frame rate.
        qp, qt: bit depths of the source's positions and UVs.
        min_pos, max_pos: the sequence's box.
        resolution: the PSNR peak (default the box's longest side).
        input_faces: the sheet's input face count (``None``: counted from the source frames).
    """

    name: str
    seq_id: int
    cls: str
    source: str
    source_texture: str | None
    first_frame: int
    frame_count: int
    fps: float
    qp: int
    qt: int
    min_pos: tuple[float, float, float]
    max_pos: tuple[float, float, float]
    resolution: float
    input_faces: int | None = None

    @property
    def frames(self) -> range:
        """The frame numbers."""
        return range(self.first_frame, self.first_frame + self.frame_count)


@dataclass(frozen=True)
class CtcCondition:
    """A test condition: ``CondId``, name, its rate points (``RateId``) and whether it is lossless."""

    cond_id: int
    name: str
    rates: tuple[int, ...]
    lossless: bool = False


@dataclass(frozen=True)
class CtcCodec:
    """A codec's outputs: decoded frames per point, and where its bits, runtimes and memory come from.

    Attributes:
        name: its name in the reports.
        decoded: template of the decoded frames (``{sequence}``... and a printf frame field; the manifest's
            folder escaped: ``{{``, ``}}``, ``%%``).
        decoded_texture: template of their textures, or ``None``.
        decoded_qt: UV bit depth of the decoded frames (the test model: 0).
        csv: the test model's CSV of this codec, or ``None``.
        bitstream: template of the bitstream file (bits = size * 8), or ``None``.
        encoder_log, decoder_log: templates of the encoder's and decoder's logs, or ``None``.
        points: ``(seq_id, cond_id, rate_id)`` -> given values (``total_bits``, ``components``, ...).
    """

    name: str
    decoded: str
    decoded_texture: str | None = None
    decoded_qt: int = 0
    csv: Path | None = None
    bitstream: str | None = None
    encoder_log: str | None = None
    decoder_log: str | None = None
    points: dict[tuple[int, int, int], dict[str, Any]] = field(default_factory=dict)


@dataclass(frozen=True)
class CtcCampaign:
    """A parsed CTC campaign manifest.

    Attributes:
        sequences, conditions: in manifest order.
        anchor, test: the two codecs.
        cache_dir: the per-frame cache folder (default ``ctc-cache`` beside the manifest), or ``None`` (no cache:
            the manifest's ``cache_dir = ""``).
        grid_size, ibsm_resolution, ibsm_cameras: the chain's settings (``ibsm_resolution`` ``None``: no IBSM).
        path: the manifest file.

    Example:
        >>> import os, tempfile
        >>> lines = ["[[sequences]]", 'name = "a"', "id = 1", 'source = "a/src_%04d.obj"', "first_frame = 0",
        ...          "frame_count = 2", "fps = 30", "qp = 10", "qt = 0", "min_pos = [0, 0, 0]",
        ...          "max_pos = [1023, 1023, 511]", "[[conditions]]", "id = 1", "rates = [1, 2]", "[anchor]",
        ...          'decoded = "anchor/r{rate_id}_%04d.obj"', "[test]", 'decoded = "test/r{rate_id}_%04d.obj"',
        ...          "[options]", 'cache_dir = ""']
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     path = os.path.join(folder, "c.toml")
        ...     with open(path, "w") as f:
        ...         _ = f.write(chr(10).join(lines))
        ...     c = load_ctc_campaign(path)
        >>> [s.name for s in c.sequences], c.conditions[0].rates, c.test.name, c.cache_dir, c.grid_size
        (['a'], (1, 2), 'test', None, 1024)
    """

    sequences: list[CtcCampaignSequence]
    conditions: list[CtcCondition]
    anchor: CtcCodec
    test: CtcCodec
    cache_dir: Path | None
    grid_size: int
    ibsm_resolution: int | None
    ibsm_cameras: int
    path: Path

    def settings(self, seq: CtcCampaignSequence, decoded_qt: int) -> CtcSettings:
        """The chain's settings of a sequence's frames decoded with UV bit depth ``decoded_qt``."""
        return CtcSettings(
            qp=seq.qp,
            qt=seq.qt,
            min_pos=seq.min_pos,
            max_pos=seq.max_pos,
            resolution=seq.resolution,
            decoded_qt=decoded_qt,
            grid_size=self.grid_size,
            ibsm_resolution=self.ibsm_resolution,
            ibsm_cameras=self.ibsm_cameras,
        )

    def input_files(self) -> list[tuple[str, str | Path | None]]:
        """``(what, path)`` of every file the campaign reads (the output check refuses an output among them).

        The manifest, the codecs' CSVs, and per sequence, condition, rate and frame the source and decoded frames,
        their textures, bitstreams and logs.
        """
        files: list[tuple[str, str | Path | None]] = [("MANIFEST", self.path)]
        for table, codec in (("anchor", self.anchor), ("test", self.test)):
            files.append((f"[{table}] csv", codec.csv))
        for seq in self.sequences:
            for k in seq.frames:
                files.append((f"{seq.name} source", frame_path(seq.source, k)))
                if seq.source_texture is not None:
                    files.append((f"{seq.name} source texture", frame_path(seq.source_texture, k)))
            for cond in self.conditions:
                for rate in cond.rates:
                    for codec in (self.anchor, self.test):
                        where = f"{codec.name} {seq.name} c{cond.cond_id} r{rate}"
                        for template in (codec.bitstream, codec.encoder_log, codec.decoder_log):
                            if template is not None:
                                files.append((where, codec_path(template, seq, cond.cond_id, rate)))
                        for template in (codec.decoded, codec.decoded_texture):
                            if template is not None:
                                pattern = codec_path(template, seq, cond.cond_id, rate)
                                files += [(f"{where} decoded", frame_path(pattern, k)) for k in seq.frames]
        return files


def codec_path(template: str, seq: CtcCampaignSequence, cond_id: int, rate_id: int) -> str:
    """A codec's file for one point: the template's ``{sequence}``, ``{seq_id}``, ``{cond_id}``, ``{rate_id}`` filled.

    Example:
        >>> s = CtcCampaignSequence("ball", 3, "cat1-B", "s_%04d.obj", None, 0, 2, 30.0, 10, 12, (0, 0, 0),
        ...                         (1, 1, 1), 1.0)
        >>> codec_path("out/s{seq_id}c{cond_id}r{rate_id}_{sequence}/dec_%04d.obj", s, 1, 2)
        'out/s3c1r2_ball/dec_%04d.obj'
    """
    return template.format(sequence=seq.name, seq_id=seq.seq_id, cond_id=cond_id, rate_id=rate_id)


class _Table:
    """A TOML table read key by key, every error naming the file and the key's path."""

    def __init__(self, data: Any, where: str, keys: tuple[str, ...]) -> None:
        if not isinstance(data, dict):
            raise CtcManifestError(f"{where}: expected a table, found {type(data).__name__}")
        unknown = sorted(set(data) - set(keys))
        if unknown:
            raise CtcManifestError(f"{where}: unknown key {unknown[0]!r} (expected one of {', '.join(keys)})")
        self.data, self.where = data, where

    def get(self, key: str, kind: type | tuple[type, ...], default: Any = ..., *, what: str = "") -> Any:
        if key not in self.data:
            if default is ...:
                raise CtcManifestError(f"{self.where}: missing key {key!r}{f' ({what})' if what else ''}")
            return default
        value = self.data[key]
        kinds = kind if isinstance(kind, tuple) else (kind,)
        if (isinstance(value, bool) and bool not in kinds) or not isinstance(value, kinds):
            raise CtcManifestError(f"{self.where}: {key!r} must be {kind_name(kinds)}, found {value!r}")
        return value

    def int_in(self, key: str, low: int, high: int, default: Any = ...) -> Any:
        value = self.get(key, int, default)
        if value is not None and value is not default and not low <= value <= high:
            raise CtcManifestError(f"{self.where}: {key!r} must be an integer in {low}..{high}, found {value}")
        return value

    def number(self, key: str, default: Any = ..., *, positive: bool = True) -> Any:
        value = self.get(key, (int, float), default)
        if value is default:
            return value
        if not math.isfinite(value) or (positive and value <= 0):
            raise CtcManifestError(f"{self.where}: {key!r} must be a positive finite number, found {value!r}")
        return float(value)

    def text(self, key: str, default: Any = ...) -> Any:
        value = self.get(key, str, default)
        if value is not default and value == "":
            raise CtcManifestError(f"{self.where}: {key!r} must be a non-empty string")
        return value


def _corner(t: _Table, key: str) -> tuple[float, float, float]:
    value = t.get(key, list)
    if len(value) != 3 or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in value):
        raise CtcManifestError(f"{t.where}: {key!r} must be three numbers, found {value!r}")
    if not all(math.isfinite(x) for x in value):
        raise CtcManifestError(f"{t.where}: {key!r} must be finite, found {value!r}")
    return (float(value[0]), float(value[1]), float(value[2]))


def _pattern(t: _Table, key: str, base: Path, *, printf: bool, template: bool, required: bool = True) -> str | None:
    """A path or pattern relative to the manifest: the user's value checked, then joined to the manifest's folder.

    ``printf``: a frame pattern (one printf integer field); ``template``: ``{sequence}``... fields. The checks run on
    the value the user wrote, and the folder joined to it is escaped for what the path goes through (``%`` as ``%%``
    in a frame pattern, braces doubled in a template): checked and filled as a whole, a manifest in a folder named
    ``50%`` or ``a{x}`` was refused, the error blaming the user's key (review R #4).
    """
    value = t.text(key) if required else t.text(key, None)
    if value is None:
        return None
    if printf:
        _check_frame_field(t.where, key, value, template=template)
    elif template:
        _check_template(t.where, key, value)
    if Path(value).is_absolute():
        return str(Path(value))
    folder = str(base)
    if template:
        folder = folder.replace("{", "{{").replace("}", "}}")
    if printf:
        folder = folder.replace("%", "%%")
    return str(Path(folder) / value)


def _check_frame_field(where: str, key: str, pattern: str, *, template: bool) -> None:
    try:
        filled = pattern.format(sequence="s", seq_id=1, cond_id=1, rate_id=1) if template else pattern
        frame_path(filled, 0, key)
    except (KeyError, IndexError) as exc:
        raise CtcManifestError(
            f"{where}: {key!r}: unknown field {exc} (expected {{sequence}}, {{seq_id}}, {{cond_id}}, {{rate_id}})"
        ) from None
    except ValueError as exc:
        raise CtcManifestError(f"{where}: {exc}") from None


def _check_template(where: str, key: str, template: str) -> None:
    try:
        template.format(sequence="s", seq_id=1, cond_id=1, rate_id=1)
    except (KeyError, IndexError, ValueError) as exc:
        raise CtcManifestError(
            f"{where}: {key!r}: bad template field {exc} (expected {{sequence}}, {{seq_id}}, {{cond_id}}, {{rate_id}})"
        ) from None


def _sequence(entry: Any, where: str, base: Path) -> CtcCampaignSequence:
    keys = (
        "name",
        "id",
        "class",
        "source",
        "source_texture",
        "first_frame",
        "frame_count",
        "fps",
        "qp",
        "qt",
        "min_pos",
        "max_pos",
        "resolution",
        "input_faces",
    )
    t = _Table(entry, where, keys)
    name = t.text("name")
    t.where = f"{where.rsplit(':', 1)[0]}: sequence {name!r}"
    lo, hi = _corner(t, "min_pos"), _corner(t, "max_pos")
    try:  # the ctc command's check: a box flat on one axis is accepted by both (review R #9)
        check_box(lo, hi, ("'min_pos'", "'max_pos'"))
    except ValueError as exc:
        raise CtcManifestError(f"{t.where}: {exc}") from None
    source = _pattern(t, "source", base, printf=True, template=False)
    texture = _pattern(t, "source_texture", base, printf=True, template=False, required=False)
    faces = t.get("input_faces", int, None)
    if faces is not None and faces <= 0:
        raise CtcManifestError(f"{t.where}: 'input_faces' must be positive, found {faces}")
    return CtcCampaignSequence(
        name=name,
        seq_id=t.int_in("id", 0, 10**9),
        cls=t.text("class", "all"),
        source=source or "",
        source_texture=texture,
        first_frame=t.int_in("first_frame", 0, 10**9),
        frame_count=t.int_in("frame_count", 1, 10**9),
        fps=t.number("fps"),
        qp=t.int_in("qp", 7, 31),
        qt=t.int_in("qt", 0, 31),
        min_pos=lo,
        max_pos=hi,
        resolution=t.number("resolution", box_longest_side(lo, hi)),
        input_faces=faces,
    )


def _condition(entry: Any, where: str) -> CtcCondition:
    t = _Table(entry, where, ("id", "name", "rates", "lossless"))
    cond_id = t.int_in("id", 0, 10**9)
    t.where = f"{where.rsplit(':', 1)[0]}: condition {cond_id}"
    rates = t.get("rates", list)
    if not rates or any(isinstance(r, bool) or not isinstance(r, int) or r < 0 for r in rates):
        raise CtcManifestError(f"{t.where}: 'rates' must be a non-empty list of RateIds (integers >= 0), found {rates}")
    if len(set(rates)) != len(rates):
        raise CtcManifestError(f"{t.where}: 'rates' repeats a RateId: {rates}")
    return CtcCondition(cond_id, t.text("name", f"C{cond_id}"), tuple(rates), t.get("lossless", bool, False))


def _codec(entry: Any, where: str, base: Path, seq_ids: dict[str, int], conds: dict[int, CtcCondition]) -> CtcCodec:
    keys = (
        "name",
        "decoded",
        "decoded_texture",
        "decoded_qt",
        "csv",
        "bitstream",
        "encoder_log",
        "decoder_log",
        "points",
    )
    t = _Table(entry, where, keys)
    decoded = _pattern(t, "decoded", base, printf=True, template=True)
    texture = _pattern(t, "decoded_texture", base, printf=True, template=True, required=False)
    templates = {
        k: _pattern(t, k, base, printf=False, template=True, required=False)
        for k in ("bitstream", "encoder_log", "decoder_log")
    }
    csv_name = t.text("csv", None)
    points: dict[tuple[int, int, int], dict[str, Any]] = {}
    for i, raw in enumerate(t.get("points", list, [])):
        p = _Table(raw, f"{where}.points[{i}]", ("sequence", "condition", "rate", "components", *_POINT_NUMBERS))
        seq = p.text("sequence")
        if seq not in seq_ids:
            raise CtcManifestError(f"{p.where}: 'sequence' {seq!r} is not a sequence of the manifest")
        cond = p.int_in("condition", 0, 10**9)
        if cond not in conds:
            raise CtcManifestError(f"{p.where}: 'condition' {cond} is not a condition of the manifest")
        rate = p.int_in("rate", 0, 10**9)
        if rate not in conds[cond].rates:
            raise CtcManifestError(f"{p.where}: 'rate' {rate} is not a rate of condition {cond}")
        values: dict[str, Any] = {k: p.number(k, None, positive=False) for k in _POINT_NUMBERS}
        values = {k: v for k, v in values.items() if v is not None}
        for k, v in values.items():
            if v < 0:
                raise CtcManifestError(f"{p.where}: {k!r} must be >= 0, found {v}")
        if values.get("total_bits") == 0:  # a coded point has bits: 0 made its BD-rates vanish from the summary
            raise CtcManifestError(f"{p.where}: 'total_bits' must be > 0 (a coded point's bitstream), found 0")
        comps = p.get("components", dict, None)
        if comps is not None:
            c = _Table(comps, f"{p.where}.components", _COMPONENTS)
            values["components"] = {k: c.number(k, positive=False) for k in comps}
            if any(v < 0 for v in values["components"].values()):
                raise CtcManifestError(f"{p.where}.components: bits must be >= 0, found {comps}")
        point = (seq_ids[seq], cond, rate)
        if point in points:
            raise CtcManifestError(f"{p.where}: repeats the point ({seq!r}, condition {cond}, rate {rate})")
        points[point] = values
    return CtcCodec(
        name=t.text("name", where.rsplit("[", 1)[-1].rstrip("]").split()[-1]),
        decoded=decoded or "",
        decoded_texture=texture,
        decoded_qt=t.int_in("decoded_qt", 0, 31, 0),
        csv=None if csv_name is None else base / csv_name,
        bitstream=templates["bitstream"],
        encoder_log=templates["encoder_log"],
        decoder_log=templates["decoder_log"],
        points=points,
    )


def load_ctc_campaign(path: str | Path) -> CtcCampaign:
    """Read and check a CTC campaign manifest (see the module); paths resolved against its folder.

    Args:
        path: the manifest (TOML): ``[[sequences]]``, ``[[conditions]]``, ``[anchor]``, ``[test]`` and optional
            ``[options]``.

    Returns:
        :class:`CtcCampaign`: the sequences and conditions in manifest order, the two codecs, the cache folder
        (default ``ctc-cache`` beside the manifest) and the chain's settings.

    Raises:
        CtcManifestError: the file is missing or not TOML, a key is missing, unknown or of the wrong type, a name or
            id is repeated, a frame pattern lacks its printf field (naming the file and the key).

    Example:
        >>> import os, tempfile
        >>> d = tempfile.mkdtemp()
        >>> text = '''
        ... [[sequences]]
        ... name = "a"
        ... id = 1
        ... source = "a/src_%04d.obj"
        ... first_frame = 0
        ... frame_count = 2
        ... fps = 30
        ... qp = 10
        ... qt = 0
        ... min_pos = [0, 0, 0]
        ... max_pos = [1023, 1023, 511]
        ... [[conditions]]
        ... id = 1
        ... rates = [1, 2]
        ... [anchor]
        ... decoded = "anchor/{sequence}_r{rate_id}_%04d.obj"
        ... [test]
        ... decoded = "test/{sequence}_r{rate_id}_%04d.obj"
        ... '''
        >>> with open(os.path.join(d, "c.toml"), "w") as f:
        ...     _ = f.write(text)
        >>> c = load_ctc_campaign(os.path.join(d, "c.toml"))
        >>> c.sequences[0].resolution, c.conditions[0].rates, c.anchor.name, c.cache_dir == Path(d) / "ctc-cache"
        (1023.0, (1, 2), 'anchor', True)
    """
    file = Path(path)
    data = read_manifest(file, "CTC campaign manifest", CtcManifestError)
    where = f"CTC campaign manifest {str(file)!r}"
    top = _Table(data, where, ("options", "sequences", "conditions", "anchor", "test"))
    base = file.parent
    opt = _Table(
        top.get("options", dict, {}), f"{where}: options", ("cache_dir", "grid_size", "ibsm_resolution", "ibsm_cameras")
    )
    # the docs' default: a rerun resumes (found by review R #3: without the key no cache was used, and every rerun
    # computed every frame again); "" keeps no cache
    cache = opt.get("cache_dir", str, DEFAULT_CACHE_DIR)
    sequences = [
        _sequence(e, f"{where}: sequences[{i}]", base)
        for i, e in enumerate(top.get("sequences", list, what="at least one [[sequences]]"))
    ]
    conditions = [
        _condition(e, f"{where}: conditions[{i}]")
        for i, e in enumerate(top.get("conditions", list, what="at least one [[conditions]]"))
    ]
    if not sequences or not conditions:
        raise CtcManifestError(f"{where}: expected at least one [[sequences]] and one [[conditions]]")
    for kind, items in (
        ("sequence name", [s.name for s in sequences]),
        ("sequence id", [s.seq_id for s in sequences]),
        ("condition id", [c.cond_id for c in conditions]),
    ):
        seen = [x for i, x in enumerate(items) if x in items[:i]]
        if seen:
            raise CtcManifestError(f"{where}: {kind} {seen[0]!r} repeats")
    seq_ids = {s.name: s.seq_id for s in sequences}
    conds = {c.cond_id: c for c in conditions}
    anchor = _codec(
        top.get("anchor", dict, what="the anchor's [anchor] table"), f"{where}: [anchor]", base, seq_ids, conds
    )
    test = _codec(
        top.get("test", dict, what="the tested codec's [test] table"), f"{where}: [test]", base, seq_ids, conds
    )
    if test.name == anchor.name:  # the summary's columns and the RD plots' legends are labelled by these names
        raise CtcManifestError(
            f"{where}: [test] name {test.name!r} is the anchor's name too: the reports could not tell the codecs "
            "apart (give one of them another 'name')"
        )
    ibsm = opt.int_in("ibsm_resolution", 0, 1 << 15, 2048)
    return CtcCampaign(
        sequences=sequences,
        conditions=conditions,
        anchor=anchor,
        test=test,
        cache_dir=base / cache if cache else None,
        grid_size=opt.int_in("grid_size", 2, 1 << 20, 1024),
        ibsm_resolution=ibsm or None,
        ibsm_cameras=opt.int_in("ibsm_cameras", 2, 4096, 16),
        path=file,
    )
