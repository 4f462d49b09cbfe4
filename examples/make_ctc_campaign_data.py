"""Make the data of examples/ctc_campaign.toml: a small V-DMC campaign made with the library, in seconds.

Two sequences ("sphere", class cat1-A, and "ellipsoid", cat1-B) of 5 frames: a deforming icosphere quantised to
10 bits (positions over the box [-1, 1]^3) with UVs quantised to 8 bits and a texture per frame, as the test model's
quantised sources are. Two codecs ("anchor" and "test"), condition 1 at rates 1 and 2: decoded frames in the same
integer space (positions moved by up to ``noise`` steps, float UVs, the texture with noise), the coarser the rate the
noisier, the test codec a little cleaner than the anchor. The anchor's bits and runtimes come as the test model's
CSV (anchor.csv); the test codec's are in the manifest. Every value is an integer or a rounding of one (the same
files on every CPU). Beside the data it writes ``ctc_campaign.toml``, the manifest examples/ctc_campaign.toml with
its paths relative to that folder, so the campaign runs on data written anywhere::

    PYTHONPATH=. python examples/make_ctc_campaign_data.py examples/ctc-campaign-data
    torchmeshmetric ctc-campaign examples/ctc_campaign.toml --out-dir ctc-report
    # or, for data written elsewhere:
    torchmeshmetric ctc-campaign OUTPUT_FOLDER/ctc_campaign.toml --out-dir ctc-report
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

#: (name, SeqId, frames, seed of its deformation)
SEQUENCES = (("sphere", 1, 5, 0), ("ellipsoid", 2, 5, 1))
#: codec -> rate -> (position noise in quantisation steps, texture noise in grey levels)
NOISE = {"anchor": {1: (4, 24), 2: (2, 10)}, "test": {1: (3, 20), 2: (1, 8)}}
#: the anchor's bits per rate (its CSV); the test codec's are 90 % of them (the manifest's points)
ANCHOR_BITS = {1: 40000, 2: 90000}


def _icosphere() -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    s = trimesh.creation.icosphere(2)
    return np.asarray(s.vertices, np.float64), np.asarray(s.faces, np.int64)


def _obj(path: Path, verts: np.ndarray, uvs: np.ndarray, faces: np.ndarray, fmt: str) -> None:
    lines = ["v " + " ".join(format(x, fmt) for x in v) for v in verts]
    lines += ["vt " + " ".join(format(x, fmt) for x in t) for t in uvs]
    lines += ["f " + " ".join(f"{i + 1}/{i + 1}" for i in f) for f in faces]
    path.write_text("\n".join(lines) + "\n")


def _png(path: Path, image: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(image.astype(np.uint8), "RGB").save(path)


def make(root: Path) -> None:
    """Write the campaign's files under ``root`` (created)."""
    verts, faces = _icosphere()
    u = 0.5 + np.arctan2(verts[:, 1], verts[:, 0]) / (2 * np.pi)
    v = 0.5 + np.arcsin(np.clip(verts[:, 2], -1, 1)) / np.pi
    uv_q = np.round(np.stack([u, v], 1) * 255)  # qt = 8
    yy, xx = np.mgrid[0:32, 0:32]
    for name, _, frames, seed in SEQUENCES:
        rng = np.random.default_rng(seed)
        src = root / name / "src"
        src.mkdir(parents=True, exist_ok=True)
        base = np.stack([xx * 8, yy * 8, (xx + yy) * 4], -1) % 256
        for k in range(frames):
            scale = np.array([0.9, 0.8 - 0.02 * k, 0.7]) if name == "ellipsoid" else 0.9 - 0.03 * k
            q = np.round((verts * scale + 1) * 511.5).clip(0, 1023)
            texture = (base + 16 * k) % 256
            _obj(src / f"src_{k:04d}.obj", q, uv_q, faces, ".0f")
            _png(src / f"src_{k:04d}.png", texture)
            for codec, rates in NOISE.items():
                for rate, (pos_noise, tex_noise) in rates.items():
                    out = root / name / codec / f"r{rate}"
                    out.mkdir(parents=True, exist_ok=True)
                    dq = (q + rng.integers(-pos_noise, pos_noise + 1, q.shape)).clip(0, 1023)
                    uv = uv_q / 255  # the decoder's UVs: floats in [0, 1] (decoded_qt = 0)
                    _obj(out / f"dec_{k:04d}.obj", dq, uv, faces, ".9g")
                    noisy = texture + rng.integers(-tex_noise, tex_noise + 1, texture.shape)
                    _png(out / f"dec_{k:04d}.png", noisy.clip(0, 255))
    rows = [
        "SeqId,CondId,RateId,NbOutputFaces,TotalBitstreamBits,GridD1,GridD2,GridLuma,GridChromaCb,GridChromaCr,"
        "IbsmGeom,IbsmLuma,UserEncoderRuntime,UserDecoderRuntime,PeakEncoderMemory,PeakDecoderMemory"
    ]
    for _, seq_id, frames, _ in SEQUENCES:
        for rate, bits in ANCHOR_BITS.items():
            # metrics left to the campaign (it computes them); the other columns as the scripts collect them
            rows.append(
                f"{seq_id},1,{rate},{frames * faces.shape[0]},{bits + 1000 * seq_id},0,0,0,0,0,,,"
                f"{10 + rate + seq_id},{1 + rate},{200 + 10 * rate},{100 + 5 * rate}"
            )
    (root / "anchor.csv").write_text("\n".join(rows) + "\n")


#: The example's manifest: its paths name the data in ``ctc-campaign-data/`` beside it.
EXAMPLE_MANIFEST = Path(__file__).resolve().parent / "ctc_campaign.toml"


def write_manifest(root: Path) -> Path:
    """``root/ctc_campaign.toml``: the example's manifest with its paths relative to ``root``, the data's folder."""
    text = EXAMPLE_MANIFEST.read_text()
    manifest = root / "ctc_campaign.toml"
    header = "# Written by examples/make_ctc_campaign_data.py: examples/ctc_campaign.toml, paths relative to here.\n"
    manifest.write_text(header + text.replace('"ctc-campaign-data/', '"'))
    return manifest


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", type=Path, metavar="OUTPUT_FOLDER", help="folder for the campaign's files (created)")
    args = parser.parse_args()  # --help / -h print the usage; they named the output folder, which was written
    make(args.out)
    # the manifest that reads this folder: examples/ctc_campaign.toml reads examples/ctc-campaign-data only
    manifest = write_manifest(args.out)
    print(f"wrote {args.out}; run: torchmeshmetric ctc-campaign {manifest} --out-dir ctc-report")
