"""Benchmark: accuracy and speed of check point matching (`measure checkpoints`) against AROSICS.

Usage::

    .venv/bin/python benchmarks/matching.py [--n 100] [--quick] [--peer-python PATH]
        [--skip-throughput] [--size 20000] [--points 1000]

**Synthetic truth** (issue 29). Every pair is two GeoTIFFs written to a temporary folder: a
reference chip and a delivered image, both cut from ``../shared/data/real/RGB.byte.tif`` (Landsat 7,
300 m, 3 bands). The reference chip is the scene's own pixels around the point, on the scene's own
georeference; the delivered image (128 x 128 px, north-up, on the nominal grid) shows the scene
displaced by a known amount: each image pixel samples the scene (interpolating cubic B-spline of
the scene upsampled 4 times in the Fourier domain, i.e. band-limited) at ``C + R(theta) (q - C) -
d``, so the point C appears at ``C + R(theta)^-1 d``, the
truth. Families (``--n`` pairs each, points drawn on land where the clean chip's standard deviation
is >= 8 DN, an independent texture criterion):

=============== =================================================================================
shift           |d| 0-5 px (uniform direction), 1:1, noise SNR 100
gain-offset     image DN x 0.6-1.4 + (-30..30)
gamma           image DN ** 0.6-1.6
season          the bands remixed (R' = .7R + .3G ...: another season's band weights)
snr-20          noise SNR 20 (sigma = luminance std / SNR, each band)
ref-1:2         the reference at 600 m (2 x 2 means), the image at 300 m
image-1:2       the image at 600 m (means of 2 x 2 samples), the reference at 300 m
rotation-1deg   the image rotated by +-1 deg about the point
combined        all of the above drawn at random per pair (SNR 20-100)
no-texture      a flat field (smooth +-3 DN relief, noise 1.5 DN) in both
cloud           a bright (235 DN) smooth cloud over 30-100 % of the template area
=============== =================================================================================

Errors are in delivered-image pixels, |measured - truth| (2-D). Targets: median <= 0.1 px and
95th percentile <= 0.3 px on accepted points, >= 95 % of textured points accepted, wrong accepted
matches (error > 1 px) <= 0.5 %, every no-texture and cloud pair on the hand list.

**Peer**: AROSICS (``arosics.COREG``, the open co-registration tool of the field) on the same files,
same windows (64 image px of ground), same search range, in its own environment
(``--peer-python``, default /work/wt/matching-peers/venv/bin/python; it needs GDAL's Python
bindings, so it is never a dependency of orthospec). A point counts as accepted by AROSICS when
``COREG.success`` is true. Time per point is measured in each process around the per-point call
(reading the windows included; imports excluded): CPU time (``time.process_time``, all threads)
and wall time, load printed beside it.

**Throughput**: ``orthospec measure checkpoints`` as a subprocess on a generated delivery of one
``--size`` x ``--size`` px, 3-band, tiled, deflate GeoTIFF (the Landsat scene mirrored over it, its
georeference off by (+0.30, -0.45) px) with ``--points`` surveyed points and a chip library of as
many 96 px chips: wall time per point (start-up and hashing the image included), peak RSS
(``ru_maxrss`` of the child), and the accuracy against the known offset.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import rasterio
from rasterio.transform import Affine
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT.parent / "shared" / "data" / "real" / "RGB.byte.tif"
PEER = Path("/work/wt/matching-peers/venv/bin/python")
IMAGE_PX = 128
CHIP_PX = 96
TEMPLATE_PX = 64
SEARCH_PX = 16
FAMILIES = (
    "shift",
    "gain-offset",
    "gamma",
    "season",
    "snr-20",
    "ref-1:2",
    "image-1:2",
    "rotation-1deg",
    "combined",
    "no-texture",
    "cloud",
)
HAND_ONLY = ("no-texture", "cloud")
#: Gaussian PSF (px) given to the scene first: the 300 m file was decimated and is aliased, and an
#: aliased scene has no single truth at a fractional shift (a cubic-spline rendering moves its
#: finest texture by up to 0.03 px depending on the fraction); a real camera's PSF removes that
PSF_SIGMA = 0.5
#: the scene window rendered around a point (scene px either way) and its Fourier upsampling: a
#: cubic spline on the 4x band-limited upsampling renders a fractional shift within 0.001 px, on the
#: raw pixels it was 0.04 px off (0.21 px for a 0.25 px shift)
#: the spline's reach and the largest displacement (5 image px = 10 scene px at 1:2) beyond the footprint
RENDER_MARGIN = 12


def render_half(ratio: str, rotated: bool) -> int:
    """Half-side (scene px) of the scene window a delivered image is rendered from: its footprint
    (x 1.05 when rotated by up to 1 deg) plus RENDER_MARGIN. The scene's valid area (a rotated
    Landsat footprint) holds no axis-parallel square over about 300 px, so the margin is kept tight."""
    scale = 2 if ratio == "image-1:2" else 1
    return int(IMAGE_PX / 2 * scale * (1.05 if rotated else 1.0)) + RENDER_MARGIN


def family_half(family: str) -> int:
    """The largest render half-window a pair of this family may need (``centres`` keeps it valid)."""
    if family in ("image-1:2", "combined"):
        return render_half("image-1:2", family == "combined")
    return render_half("1:1", family == "rotation-1deg")


UPSAMPLE = 4


def _upsampled(bands: np.ndarray) -> np.ndarray:
    """Spline coefficients of the bands upsampled UPSAMPLE times by zero-padding their spectrum
    (sample k of the input is sample UPSAMPLE * k of the output)."""
    from scipy.signal import resample

    up = bands
    for axis in (1, 2):
        up = resample(up, up.shape[axis] * UPSAMPLE, axis=axis)
    return np.stack([ndimage.spline_filter(b, order=3) for b in up])


SEASON = np.array([[0.7, 0.3, 0.0], [0.1, 0.8, 0.1], [0.0, 0.4, 0.6]])


def load() -> str:
    return os.getloadavg().__repr__() if hasattr(os, "getloadavg") else "?"


@dataclass
class Scene:
    bands: np.ndarray  # (3, H, W) float64
    transform: Affine
    crs: str
    valid: np.ndarray


def scene() -> Scene:
    with rasterio.open(SCENE) as ds:
        raw = ds.read().astype(np.float64)
        t, crs = ds.transform, ds.crs.to_wkt()
    # outside the footprint every band is 0; inside, a dark pixel may be 0 in one band
    valid = (raw > 0).any(axis=0)
    bands = np.stack([ndimage.gaussian_filter(b, PSF_SIGMA) for b in raw])
    return Scene(bands, t, crs, valid)


@dataclass
class Pair:
    family: str
    index: int
    image: str
    reference: str
    x: float  # true position of the point (map)
    y: float
    truth_dx: float  # where the point appears in the image minus where it is, image px (col)
    truth_dy: float  # (row, down)
    image_px: float
    reference_px: float
    kind: str  # textured | flat | cloud


def centres(
    sc: Scene, rng: np.random.Generator, n: int, *, half: int, min_std: float = 8.0
) -> list[tuple[int, int]]:
    """Scene pixels (row, col) whose surroundings (``half`` px either way) are valid and whose 64 px
    chip is textured. Raises when the scene has no such place (an endless draw otherwise)."""
    h, w = sc.valid.shape
    if min(h, w) <= 2 * half:
        raise ValueError(f"the scene ({w} x {h} px) is smaller than a {2 * half} px window")
    lum = sc.bands.mean(axis=0)
    out: list[tuple[int, int]] = []
    tries = 0
    while len(out) < n:
        tries += 1
        if tries > 200 * n + 10_000:
            raise RuntimeError(
                f"{len(out)} of {n} centres with a valid {2 * half} px window found in "
                f"{tries - 1} draws: the scene's valid area is too small for this window"
            )
        r, c = int(rng.integers(half, h - half)), int(rng.integers(half, w - half))
        if not sc.valid[r - half : r + half, c - half : c + half].all():
            continue
        if lum[r - 32 : r + 32, c - 32 : c + 32].std() < min_std:
            continue
        out.append((r, c))
    return out


def params(family: str, rng: np.random.Generator) -> dict[str, float | bool | str]:
    mag, ang = rng.uniform(0, 5), rng.uniform(0, 2 * math.pi)
    p: dict[str, float | bool | str] = {
        "dx": mag * math.cos(ang),
        "dy": mag * math.sin(ang),
        "theta": 0.0,
        "gain": 1.0,
        "offset": 0.0,
        "gamma": 1.0,
        "season": False,
        "snr": 100.0,
        "ratio": "1:1",
        "cloud": 0.0,
        "flat": False,
    }
    if family == "gain-offset":
        p.update(gain=rng.uniform(0.6, 1.4), offset=rng.uniform(-30, 30))
    elif family == "gamma":
        p.update(gamma=rng.uniform(0.6, 1.6))
    elif family == "season":
        p.update(season=True)
    elif family == "snr-20":
        p.update(snr=20.0)
    elif family == "ref-1:2":
        p.update(ratio="ref-1:2")
    elif family == "image-1:2":
        p.update(ratio="image-1:2")
    elif family == "rotation-1deg":
        p.update(theta=float(rng.choice([-1.0, 1.0])) * rng.uniform(0.5, 1.0))
    elif family == "combined":
        p.update(
            gain=rng.uniform(0.6, 1.4),
            offset=rng.uniform(-30, 30),
            gamma=rng.uniform(0.6, 1.6),
            season=bool(rng.integers(2)),
            snr=rng.uniform(20, 100),
            theta=rng.uniform(-1, 1),
            ratio=str(rng.choice(["1:1", "ref-1:2", "image-1:2"])),
        )
    elif family == "no-texture":
        p.update(flat=True)
    elif family == "cloud":
        p.update(cloud=rng.uniform(0.3, 1.0))
    return p


def _write(path: Path, arr: np.ndarray, transform: Affine, crs: str) -> None:
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=arr.shape[2],
        height=arr.shape[1],
        count=arr.shape[0],
        dtype="uint8",
        crs=crs,
        transform=transform,
        photometric="RGB",
    ) as ds:
        ds.write(arr)


def make_pair(
    folder: Path,
    sc: Scene,
    family: str,
    index: int,
    centre: tuple[int, int],
    rng: np.random.Generator,
) -> Pair:
    """Write one reference chip and one delivered image (see the module docstring)."""
    p = params(family, rng)
    t = sc.transform
    res = abs(t.a)
    r0, c0 = centre
    x, y = t * (c0 + 0.5, r0 + 0.5)  # the point: centre of scene pixel (r0, c0)
    bands = sc.bands
    if p["flat"]:
        field = 80 + 3 * ndimage.gaussian_filter(rng.standard_normal(bands.shape[1:]), 12) * 12
        bands = np.stack([field] * 3)
    # the rendered window: the image's footprint (rotated) plus the spline's reach
    img_res = 2 * res if p["ratio"] == "image-1:2" else res
    ref_res = 2 * res if p["ratio"] == "ref-1:2" else res
    h = render_half(str(p["ratio"]), float(p["theta"]) != 0.0)
    coef = _upsampled(bands[:, r0 - h : r0 + h, c0 - h : c0 + h])
    # the delivered image: pixel (i, j) centre q; content = scene at C + R (q - C) - d
    th = math.radians(float(p["theta"]))
    cth, sth = math.cos(th), math.sin(th)
    dmx, dmy = float(p["dx"]) * img_res, -float(p["dy"]) * img_res  # displacement in map units
    x0, y0 = x - IMAGE_PX / 2 * img_res, y + IMAGE_PX / 2 * img_res
    sub = (-0.25, 0.25) if p["ratio"] == "image-1:2" else (0.0,)
    acc = np.zeros((3, IMAGE_PX, IMAGE_PX))
    jj, ii = np.meshgrid(np.arange(IMAGE_PX) + 0.5, np.arange(IMAGE_PX) + 0.5)
    for su in sub:
        for sv in sub:
            qx = x0 + (jj + su) * img_res - x
            qy = y0 - (ii + sv) * img_res - y
            sx = x + cth * qx - sth * qy - dmx
            sy = y + sth * qx + cth * qy - dmy
            col = ((sx - t.c) / t.a - 0.5 - (c0 - h)) * UPSAMPLE
            row = ((sy - t.f) / t.e - 0.5 - (r0 - h)) * UPSAMPLE
            acc += np.stack(
                [
                    ndimage.map_coordinates(b, [row, col], order=3, prefilter=False, mode="nearest")
                    for b in coef
                ]
            )
    img = acc / len(sub) ** 2
    # truth: R^-1 d in map units, to image px
    tx, ty = cth * dmx + sth * dmy, -sth * dmx + cth * dmy
    truth_dx, truth_dy = tx / img_res, -ty / img_res
    # the reference chip: the scene's own pixels (2 x 2 means for ref-1:2)
    half = CHIP_PX // 2
    ref = bands[:, r0 - half : r0 + half, c0 - half : c0 + half].copy()
    if p["ratio"] == "ref-1:2":
        ref = ref.reshape(3, half, 2, half, 2).mean(axis=(2, 4))
    ref_t = Affine(ref_res, 0, t.c + (c0 - half) * res, 0, -ref_res, t.f - (r0 - half) * res)
    # radiometry of the image
    if p["season"]:
        img = np.einsum("ab,bij->aij", SEASON, img)
    img = np.clip(img, 0, 255)
    img = 255.0 * (img / 255.0) ** float(p["gamma"])
    img = float(p["gain"]) * img + float(p["offset"])
    if float(p["cloud"]) > 0:
        blob = ndimage.gaussian_filter(rng.standard_normal((IMAGE_PX, IMAGE_PX)), 6)
        core = blob[
            IMAGE_PX // 2 - 32 : IMAGE_PX // 2 + 32, IMAGE_PX // 2 - 32 : IMAGE_PX // 2 + 32
        ]
        thr = np.quantile(core, 1 - float(p["cloud"]))
        alpha = np.clip((blob - thr) / (blob.std() * 0.3), 0, 1)
        img = img * (1 - alpha) + 235 * alpha
    if p["flat"]:
        sig_i = sig_r = 1.5
    else:
        sig_i = max(float(img.mean(axis=0).std()), 2.0) / float(p["snr"])
        sig_r = max(float(ref.mean(axis=0).std()), 2.0) / 100.0
    img = img + rng.normal(0, sig_i, img.shape)
    ref = ref + rng.normal(0, sig_r, ref.shape)
    img8 = np.clip(np.round(img), 1, 255).astype(np.uint8)
    ref8 = np.clip(np.round(ref), 1, 255).astype(np.uint8)
    stem = f"{family.replace(':', '_')}-{index:04d}"
    ipath, rpath = folder / f"{stem}-image.tif", folder / f"{stem}-ref.tif"
    _write(ipath, img8, Affine(img_res, 0, x0, 0, -img_res, y0), sc.crs)
    _write(rpath, ref8, ref_t, sc.crs)
    kind = "flat" if p["flat"] else "cloud" if float(p["cloud"]) > 0 else "textured"
    return Pair(
        family,
        index,
        str(ipath),
        str(rpath),
        float(x),
        float(y),
        truth_dx,
        truth_dy,
        img_res,
        ref_res,
        kind,
    )


def make_pairs(
    folder: Path, n: int, seed: int = 29, families: tuple[str, ...] = FAMILIES
) -> list[Pair]:
    sc = scene()
    rng = np.random.default_rng(seed)
    pairs = []
    for family in families:
        for i, c in enumerate(centres(sc, rng, n, half=family_half(family) + 2)):
            pairs.append(make_pair(folder, sc, family, i, c, rng))
    return pairs


def run_orthospec(pairs: list[Pair], method: str = "phase") -> list[dict[str, object]]:
    """Locate every pair's point with the library call ``measure checkpoints`` makes per point."""
    from orthospec.measures.matching import MatchSettings
    from orthospec.raster.checkpoints import locate
    from orthospec.raster.chips import read_header
    from orthospec.raster.reading import open_read_only, read_only_env

    settings = MatchSettings(method=method, search_px=SEARCH_PX)  # type: ignore[arg-type]
    out = []
    with read_only_env():
        for p in pairs:
            t0, c0 = time.perf_counter(), time.process_time()
            image, chip = read_header(p.image), read_header(p.reference)
            with open_read_only(p.image) as ids, open_read_only(p.reference) as cds:
                loc = locate(ids, image, cds, chip, p.x, p.y, settings, chip_px=TEMPLATE_PX)
            dt, cpu = time.perf_counter() - t0, time.process_time() - c0
            m = loc.match
            ok = m is not None and m.accepted
            dx = m.dx_px if m is not None else math.nan
            dy = m.dy_px if m is not None else math.nan
            out.append(
                {
                    "accepted": ok,
                    "dx": dx,
                    "dy": dy,
                    "seconds": dt,
                    "cpu": cpu,
                    "reason": (m.reason_code if m is not None else loc.problem) or "",
                }
            )
    return out


AROSICS_DRIVER = r"""
import json, sys, time, warnings
warnings.filterwarnings("ignore")
from arosics import COREG
jobs = json.load(open(sys.argv[1]))
out = []
for j in jobs:
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        cr = COREG(j["reference"], j["image"], wp=(j["x"], j["y"]), ws=(j["ws"], j["ws"]),
                   max_shift=j["max_shift"], q=True, ignore_errors=True, nodata=(0, 0),
                   CPUs=1, progress=False)
        cr.calculate_spatial_shifts()
        ok = bool(cr.success)
        # COREG reports the correction to apply to the target, in target pixels (x right, y down):
        # the displacement is its negative (checked on the shift family: errors stay < 1 px)
        dx = -float(cr.x_shift_px) if ok else float("nan")
        dy = -float(cr.y_shift_px) if ok else float("nan")
        err = ""
    except Exception as exc:
        ok, dx, dy, err = False, float("nan"), float("nan"), type(exc).__name__
    out.append({"accepted": ok, "dx": dx, "dy": dy, "seconds": time.perf_counter() - t0,
                "cpu": time.process_time() - c0, "reason": err})
json.dump(out, open(sys.argv[2], "w"))
"""


def run_arosics(pairs: list[Pair], python: Path, folder: Path) -> list[dict[str, object]] | str:
    """AROSICS on the same pairs in its own environment; a string says why it could not run."""
    if not python.exists():
        return f"{python} not found (AROSICS is installed only in the benchmark's peer environment)"
    jobs = []
    for p in pairs:
        coarse = max(p.image_px, p.reference_px)
        jobs.append(
            {
                "reference": p.reference,
                "image": p.image,
                "x": p.x,
                "y": p.y,
                "ws": round(TEMPLATE_PX * p.image_px / coarse),
                "max_shift": max(5, round(SEARCH_PX * p.image_px / p.reference_px)),
            }
        )
    (folder / "jobs.json").write_text(json.dumps(jobs))
    (folder / "driver.py").write_text(AROSICS_DRIVER)
    r = subprocess.run(
        [
            str(python),
            str(folder / "driver.py"),
            str(folder / "jobs.json"),
            str(folder / "arosics.json"),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    if r.returncode != 0:
        return f"AROSICS failed: {r.stderr.strip()[-500:]}"
    return json.loads((folder / "arosics.json").read_text())


def errors(pairs: list[Pair], res: list[dict[str, object]]) -> np.ndarray:
    return np.array(
        [
            math.hypot(float(r["dx"]) - p.truth_dx, float(r["dy"]) - p.truth_dy)  # type: ignore[arg-type]
            if r["accepted"]
            else math.nan
            for p, r in zip(pairs, res, strict=True)
        ]
    )


def summary(pairs: list[Pair], results: dict[str, list[dict[str, object]]]) -> list[str]:
    lines = [
        f"{'family':14s} {'tool':14s} {'accepted':>9s} {'median':>7s} {'p95':>7s} {'max':>7s} "
        f"{'>1px':>5s} {'ms/pt':>7s}  hand-list reasons"
    ]
    for family in FAMILIES:
        idx = [i for i, p in enumerate(pairs) if p.family == family]
        if not idx:
            continue
        sub = [pairs[i] for i in idx]
        for tool, res in results.items():
            r = [res[i] for i in idx]
            e = errors(sub, r)
            acc = ~np.isnan(e)
            ms = 1000 * float(np.median([float(x["seconds"]) for x in r]))  # type: ignore[arg-type]
            reasons: dict[str, int] = {}
            for x in r:
                if not x["accepted"]:
                    reasons[str(x["reason"]) or "-"] = reasons.get(str(x["reason"]) or "-", 0) + 1
            med = f"{np.median(e[acc]):7.3f}" if acc.any() else "      -"
            p95 = f"{np.percentile(e[acc], 95):7.3f}" if acc.any() else "      -"
            mx = f"{e[acc].max():7.3f}" if acc.any() else "      -"
            lines.append(
                f"{family:14s} {tool:14s} {acc.mean():9.1%} {med} {p95} {mx} {int((e[acc] > 1).sum()):5d} "
                f"{ms:7.1f}  {', '.join(f'{k} {v}' for k, v in sorted(reasons.items()))}"
            )
    return lines


def targets(pairs: list[Pair], res: list[dict[str, object]]) -> list[str]:
    e = errors(pairs, res)
    textured = np.array([p.kind == "textured" for p in pairs])
    acc = ~np.isnan(e)
    ok = acc & textured
    med, p95 = float(np.median(e[ok])), float(np.percentile(e[ok], 95))
    wrong = int((e[acc] > 1).sum())
    share = float(acc[textured].mean())
    hand = not bool(acc[~textured].any())
    return [
        f"median |error| {med:.3f} px (target <= 0.1): {'met' if med <= 0.1 else 'MISSED'}",
        f"95th percentile {p95:.3f} px (target <= 0.3): {'met' if p95 <= 0.3 else 'MISSED'}",
        f"textured points accepted {share:.1%} (target >= 95 %): {'met' if share >= 0.95 else 'MISSED'}",
        f"wrong accepted (> 1 px) {wrong} of {int(acc.sum())} = {wrong / max(int(acc.sum()), 1):.2%} "
        f"(target <= 0.5 %): {'met' if wrong <= 0.005 * acc.sum() else 'MISSED'}",
        f"no-texture and cloud pairs all on the hand list: {'met' if hand else 'MISSED'}",
    ]


# --------------------------------------------------------------------------- throughput

MANIFEST = """orthospec_delivery: 1
id: BENCH-MATCHING
project: {{id: P1, name: matching throughput, crs: "EPSG:32618"}}
contractor: {{name: Benchmark}}
operator: {{name: Benchmark}}
sensor: {{type: satellite, digital: true}}
product: {{gsd: {{value: {gsd}, unit: m}}}}
blocks: [{{id: B1}}]
tables: {{images: tables/images.csv}}
"""


def _mirror(sc: Scene, rows: slice, cols: slice) -> np.ndarray:
    """The scene mirrored periodically over any pixel range (valid area only: a 600 px square)."""
    core = sc.bands[:, 60:660, 100:700]
    h, w = core.shape[1:]
    r = np.arange(rows.start, rows.stop) % (2 * h)
    r = np.where(r < h, r, 2 * h - 1 - r)
    c = np.arange(cols.start, cols.stop) % (2 * w)
    c = np.where(c < w, c, 2 * w - 1 - c)
    return core[:, r][:, :, c]


#: the delivered image's georeference error: true P's content sits at P + OFFSET (columns, rows)
OFFSET = (0.30, -0.45)


def build_big(
    folder: Path, size: int, points: int, offset: tuple[float, float] = OFFSET, seed: int = 7
) -> tuple[Path, Path, Path]:
    """Delivery with one size x size image, a chip library and a survey (see the docstring)."""
    from rasterio.windows import Window

    sc = scene()
    res = abs(sc.transform.a)
    x0, y0 = 500000.0, 4000000.0
    true_t = Affine(res, 0, x0, 0, -res, y0)
    # the delivered image's georeference is off: content at true P sits at P + offset (px)
    deliv_t = Affine(res, 0, x0 + offset[0] * res, 0, -res, y0 - offset[1] * res)
    d = folder / "delivery"
    (d / "images").mkdir(parents=True)
    (d / "tables").mkdir()
    (d / "delivery.yaml").write_text(MANIFEST.format(gsd=res))
    (d / "tables" / "images.csv").write_text("image_id,file,block\nBIG,images/big.tif,B1\n")
    block = 512
    with rasterio.open(
        d / "images" / "big.tif",
        "w",
        driver="GTiff",
        width=size,
        height=size,
        count=3,
        dtype="uint8",
        crs=sc.crs,
        transform=deliv_t,
        tiled=True,
        blockxsize=block,
        blockysize=block,
        compress="deflate",
        zlevel=1,
        photometric="RGB",
        BIGTIFF="YES",
    ) as ds:
        for r in range(0, size, 2048):
            h = min(2048, size - r)
            for c in range(0, size, 2048):
                w = min(2048, size - c)
                ds.write(
                    np.clip(_mirror(sc, slice(r, r + h), slice(c, c + w)), 1, 255).astype(np.uint8),
                    window=Window(c, r, w, h),
                )
    chips = folder / "chips"
    chips.mkdir()
    rng = np.random.default_rng(seed)
    lines = ["point_id,x,y,source"]
    half = CHIP_PX // 2
    n = 0
    while n < points:
        r, c = int(rng.integers(200, size - 200)), int(rng.integers(200, size - 200))
        data = _mirror(sc, slice(r - half, r + half), slice(c - half, c + half))
        if data.mean(axis=0)[half - 32 : half + 32, half - 32 : half + 32].std() < 8:
            continue
        n += 1
        pid = f"P{n:05d}"
        x, y = true_t * (c + 0.5, r + 0.5)
        lines.append(f"{pid},{x:.3f},{y:.3f},benchmark")
        _write(
            chips / f"{pid}.tif",
            np.clip(data, 1, 255).astype(np.uint8),
            true_t * Affine.translation(c - half, r - half),
            sc.crs,
        )
    survey = folder / "survey.csv"
    survey.write_text("\n".join(lines) + "\n")
    return d, chips, survey


def throughput(size: int, points: int) -> list[str]:
    with tempfile.TemporaryDirectory(prefix="orthospec-bench-matching-") as tmp:
        t0 = time.perf_counter()
        d, chips, survey = build_big(Path(tmp), size, points)
        built = time.perf_counter() - t0
        out = Path(tmp) / "checker"
        exe = Path(sys.executable).with_name("orthospec")
        cmd = [
            str(exe),
            "measure",
            "checkpoints",
            str(d),
            "--reference",
            str(chips),
            "--points",
            str(survey),
            "--out",
            str(out),
            "--json",
        ]
        # a fresh parent whose only child is the command: RUSAGE_CHILDREN of this process would
        # also hold earlier children (the AROSICS run), whose peak is not the command's
        probe = (
            "import json, resource, subprocess, sys, time; t0 = time.perf_counter(); "
            "r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
            "sys.stderr.write(r.stderr); sys.stdout.write(r.stdout); "
            "open(%r, 'w').write(json.dumps({'rc': r.returncode, 'wall': time.perf_counter() - t0, "
            "'maxrss_kib': resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss}))"
        )
        stats_file = Path(tmp) / "probe.json"
        r = subprocess.run(
            [sys.executable, "-c", probe % str(stats_file), *cmd],
            capture_output=True,
            text=True,
            check=False,
        )
        stats = json.loads(stats_file.read_text())
        wall, rss = float(stats["wall"]), int(stats["maxrss_kib"])
        if stats["rc"] != 0:
            return [
                f"throughput: the command failed (exit {stats['rc']}): {r.stderr.strip()[-400:]}"
            ]
        doc = json.loads(r.stdout)
        acc = [p for p in doc["points"] if p["decision"] == "accepted"]
        # the truth: content at true P sits at P + OFFSET (image columns right, rows down)
        err = np.array([math.hypot(p["dx_px"] - OFFSET[0], p["dy_px"] - OFFSET[1]) for p in acc])
        reasons: dict[str, int] = {}
        for p in doc["points"]:
            if p["decision"] != "accepted":
                key = str(p.get("reason_code") or p["decision"])
                reasons[key] = reasons.get(key, 0) + 1
        mib = (d / "images" / "big.tif").stat().st_size / 2**20
        return [
            f"throughput: {points} points on a {size:,} x {size:,} px 3-band tiled deflate GeoTIFF "
            f"({mib:,.0f} MiB; built in {built:.0f} s)",
            f"  whole command {wall:.1f} s = {1000 * wall / points:.1f} ms per point (start-up, SHA-256 "
            f"of the image and writing included); peak RSS {rss / 1024:.0f} MiB; load {load()}",
            f"  accepted {len(acc)} of {points}; |error| median {np.median(err):.3f} px, 95th percentile "
            f"{np.percentile(err, 95):.3f} px, > 1 px {int((err > 1).sum())}; not accepted: "
            f"{', '.join(f'{k} {v}' for k, v in sorted(reasons.items())) or '-'}",
        ]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=100, help="pairs per family")
    ap.add_argument(
        "--quick", action="store_true", help="20 pairs per family, 2,000 px, 100 points"
    )
    ap.add_argument("--peer-python", type=Path, default=PEER)
    ap.add_argument("--skip-throughput", action="store_true")
    ap.add_argument("--size", type=int, default=20000)
    ap.add_argument("--points", type=int, default=1000)
    a = ap.parse_args(argv)
    if a.quick:
        a.n, a.size, a.points = 20, 2000, 100
    print(f"uptime load {load()}; {a.n} pairs per family; scene {SCENE.name}")
    with tempfile.TemporaryDirectory(prefix="orthospec-bench-matching-") as tmp:
        folder = Path(tmp)
        t0 = time.perf_counter()
        pairs = make_pairs(folder, a.n)
        print(f"{len(pairs)} pairs written in {time.perf_counter() - t0:.0f} s")
        results: dict[str, list[dict[str, object]]] = {}
        for method in ("phase", "ncc"):
            results[f"orthospec-{method}"] = run_orthospec(pairs, method)
            print(f"orthospec ({method}) done; load {load()}")
        peer = run_arosics(pairs, a.peer_python, folder)
        if isinstance(peer, str):
            print(f"AROSICS not compared: {peer}")
        else:
            results["arosics"] = peer
            print(f"AROSICS done; load {load()}")
        print()
        print("\n".join(summary(pairs, results)))
        print()
        for tool, res in results.items():
            print(f"targets, {tool}:")
            print("  " + "\n  ".join(targets(pairs, res)))
        if "arosics" in results:
            o, p = results["orthospec-phase"], results["arosics"]

            def med(res: list[dict[str, object]], key: str) -> float:
                return 1000 * float(np.median([float(x[key]) for x in res]))  # type: ignore[arg-type]

            # CPU time is what the comparison rests on: the two tools run one after the other and the
            # shared machine's load moves between them (wall time printed beside it)
            print(
                f"\ntime per point (median): CPU orthospec {med(o, 'cpu'):.1f} ms, AROSICS {med(p, 'cpu'):.1f} ms, "
                f"ratio {med(p, 'cpu') / med(o, 'cpu'):.1f}x; wall {med(o, 'seconds'):.1f} / "
                f"{med(p, 'seconds'):.1f} ms; load {load()}"
            )
            worse = []
            for family in FAMILIES:
                if family in HAND_ONLY:
                    continue
                idx = [i for i, q in enumerate(pairs) if q.family == family]
                eo = errors([pairs[i] for i in idx], [o[i] for i in idx])
                ep = errors([pairs[i] for i in idx], [p[i] for i in idx])
                if np.isnan(eo).all() or (
                    not np.isnan(ep).all() and np.nanmedian(eo) > np.nanmedian(ep)
                ):
                    worse.append(family)
            print(
                "orthospec at least as accurate as AROSICS (median |error| on accepted points) on every "
                f"family: {'yes' if not worse else 'NO: ' + ', '.join(worse)}"
            )
        if os.environ.get("ORTHOSPEC_BENCH_KEEP"):
            keep = Path(os.environ["ORTHOSPEC_BENCH_KEEP"])
            keep.mkdir(parents=True, exist_ok=True)
            (keep / "pairs.json").write_text(json.dumps([asdict(p) for p in pairs]))
            (keep / "results.json").write_text(json.dumps(results))
            shutil.copytree(folder, keep / "files", dirs_exist_ok=True)
    if not a.skip_throughput:
        print()
        print("\n".join(throughput(a.size, a.points)))


if __name__ == "__main__":
    main()
