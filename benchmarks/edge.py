"""Benchmark: accuracy and time of the edge chain over angles, PSFs and noise levels.

Usage::

    .venv/bin/python benchmarks/edge.py [--size 100] [--lines 100] [--repeats 5] [--quick]

For every (angle, PSF, SNR) it renders ``--repeats`` synthetic slanted edges
(``orthospec.measures.synthetic``, different noise seeds and sub-pixel offsets), runs
``measure_edge`` and prints, against the truth (closed form for Gaussian PSFs,
``kernel_truth`` for the measured kernels: core + halo, defocus disk, motion smear):
the fit chosen as primary (g = gauss, b = gauss-box, 2 = gauss2, u = gauss-usm, d = gauss-disk,
m = gauss-mtfc, a = airy, s = spline), the mean
and worst FWHM error (%) of the primary fit, the worst FWHM error of the model-free
spline on the same ROIs (the peer this method improves on), the worst MTF@Nyquist, RER
and angle errors and the mean CPU time per ROI (measurement only, ``time.process_time``:
wall time on a shared machine depends on its load). SNR 50 is the seed's
health-check boundary, so every ROI runs with the SNR check at 45. Target: < 0.3 s per
100 x 100 ROI. Deterministic input (seeded); timings depend on the machine.

Second table (issue 16): four blur families (Gaussian sigma 0.8 px; a 15 % halo
0.85 G(0.6) + 0.15 G(2.0); a defocus disk R = 2 px x G(0.5); a Gaussian sigma 0.8 px edge
sharpened by an unsharp mask, amount 1, sigma 1.5 px) x SNR {inf, 100, 50, 30}, 8-bit
(dark 51, bright 204 DN; SNR inf = noise-free but quantised), angles 5/12/20 deg x 3 seeds:
median and worst |error| of FWHM, RER and MTF@Nyquist against numerical truth
(``kernel_truth``, ``unsharp_truth``) and the share within target (FWHM 2 %, RER 0.02,
MTF@Ny 0.01; 0.005 at SNR inf). Those ROIs run with the SNR check at 25. Noise is added
after the sharpening (the product's SNR). ``--families-only`` skips the first table.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import fftconvolve

from orthospec.measures.edge import EdgeLimits, measure_edge
from orthospec.measures.synthetic import (
    EdgeTruth,
    FamilyTruth,
    PsfFamily,
    edge_truth,
    family_edge,
    family_truth,
    kernel_truth,
    slanted_edge,
    unsharp_mask,
    unsharp_truth,
)

ANGLES = (2.0, 5.0, 10.0, 20.0, 29.0)
SIGMAS = (0.4, 0.8, 1.5)
SNRS = (50.0, 100.0, 500.0)
S = 9  # supersampling of the render; kernels are sampled at 1/S px
CODE = {"gauss": "g", "gauss-box": "b", "gauss2": "2", "gauss-usm": "u", "gauss-disk": "d",
        "gauss-mtfc": "m", "airy": "a", "spline": "s"}


def _kernels() -> dict[str, np.ndarray]:
    r = np.arange(-80, 81) / S
    x, y = np.meshgrid(r, r)

    def gauss(sig: float) -> np.ndarray:
        g = np.exp(-0.5 * (x**2 + y**2) / sig**2)
        return g / g.sum()

    acc = np.zeros_like(x)
    for dy in (np.arange(5) + 0.5) / 5 - 0.5:
        for dx in (np.arange(5) + 0.5) / 5 - 0.5:
            acc += (x + dx / S) ** 2 + (y + dy / S) ** 2 <= 2.0**2
    motion = np.where((np.abs(x) <= 0.75) & (np.abs(y) < 0.5 / S), 1.0, 0.0)
    return {
        "_g0.6": gauss(0.6), "_g2.0": gauss(2.0),
        "halo .6+2": 0.8 * gauss(0.6) + 0.2 * gauss(2.0),
        "disk R2": fftconvolve(acc / acc.sum(), gauss(0.5), mode="same"),
        "motion1.5": fftconvolve(motion, gauss(0.5), mode="same"),
    }


def run(size: int, lines: int, repeats: int, quick: bool) -> int:
    print(f"edge chain: {lines} lines x {size} px ROIs, {repeats} seeds per row; errors vs truth")
    head = (f"{'PSF':>9} {'angle':>5} {'SNR':>4} | {'primary':>7} | {'FWHM mean%':>10} "
            f"{'max%':>5} | {'spline max%':>11} | {'MTF max':>7} | {'RER max':>7} | "
            f"{'ang max':>7} | {'s/ROI':>6}")
    print(head)
    print("-" * len(head))
    times: list[float] = []
    worst: dict[str, dict[str, float]] = {}
    within = {"gaussian": [0, 0], "measured": [0, 0]}
    cases: list[tuple[str, float, float, float | None, np.ndarray | None]] = []
    angles = (2.0, 10.0, 29.0) if quick else ANGLES
    for snr in SNRS:
        for sigma in SIGMAS:
            cases += [(f"G {sigma:g}", a, snr, sigma, None) for a in angles]
    for name, k in _kernels().items():
        if name.startswith("_"):
            continue
        for snr in SNRS:
            cases += [(name, a, snr, None, k) for a in (5.0, 20.0)]
    for label, angle, snr, sigma, kernel in cases:
        if kernel is None:
            truth = edge_truth(sigma_px=sigma, angle_deg=angle)
        else:
            truth = kernel_truth(kernel, angle_deg=angle, psf_step_px=1 / S, supersample=S)
        fw, sp, mt, rr, an, dt, prim = [], [], [], [], [], [], []
        for seed in range(repeats):
            img = slanted_edge((lines, size), angle_deg=angle, sigma_px=sigma, psf=kernel,
                               psf_step_px=1 / S, snr=snr, supersample=S, offset_px=0.137 * seed,
                               rng=np.random.default_rng(seed))
            t0 = time.process_time()
            r = measure_edge(img, limits=EdgeLimits(min_snr=45))
            dt.append(time.process_time() - t0)
            if not r.valid:
                continue
            prim.append(CODE.get(r.primary_fit, "?"))
            fw.append(r.fwhm_px / truth.fwhm_px - 1)
            sp.append(r.estimate("fwhm_px", "spline").value / truth.fwhm_px - 1)
            mt.append(abs(r.mtf_nyquist - truth.mtf_nyquist))
            rr.append(abs(r.rer - truth.rer))
            an.append(abs(r.angle_deg - angle))
        times += dt
        group = "gaussian" if kernel is None else "measured"
        key = f"{group} SNR {snr:g}"
        w = worst.setdefault(key, {"fwhm": 0.0, "spline": 0.0, "mtf": 0.0, "rer": 0.0, "angle": 0.0})
        if not fw:
            print(f"{label:>9} {angle:5.1f} {snr:4.0f} | (no valid ROI)")
            continue
        within[group][0] += sum(abs(e) <= 0.02 for e in fw)
        within[group][1] += len(fw)
        for k, vals in (("fwhm", fw), ("spline", sp)):
            w[k] = max(w[k], max(map(abs, vals)))
        for k, vals in (("mtf", mt), ("rer", rr), ("angle", an)):
            w[k] = max(w[k], max(vals))
        print(
            f"{label:>9} {angle:5.1f} {snr:4.0f} | {''.join(prim):>7} | "
            f"{100 * statistics.fmean(fw):+10.2f} {100 * max(map(abs, fw)):5.2f} | "
            f"{100 * max(map(abs, sp)):11.2f} | {max(mt):7.4f} | {max(rr):7.4f} | "
            f"{max(an):7.3f} | {statistics.fmean(dt):6.3f}"
        )
    print("-" * len(head))
    print(
        f"CPU time per ROI: mean {statistics.fmean(times):.3f} s, median "
        f"{statistics.median(times):.3f} s, max {max(times):.3f} s (target < 0.5 s)"
    )
    print("worst errors (primary fit; spline alone in brackets):")
    for key, w in worst.items():
        print(
            f"  {key:>18}: FWHM {100 * w['fwhm']:.2f} % ({100 * w['spline']:.2f} %), "
            f"MTF@Ny {w['mtf']:.4f}, RER {w['rer']:.4f}, angle {w['angle']:.3f} deg"
        )
    for group, (ok, n) in within.items():
        print(f"FWHM within 2 %: {ok}/{n} ROIs ({group} PSFs)")
    return 0


FAMILY_SNRS = (math.inf, 100.0, 50.0, 30.0)
FAMILY_ANGLES = (5.0, 12.0, 20.0)
USM = {"amount": 1.0, "mask_sigma_px": 1.5, "sigma_px": 0.8}


def _family_truth(name: str, angle: float, kernels: dict[str, np.ndarray]) -> EdgeTruth:
    if name == "gauss 0.8":
        return edge_truth(sigma_px=0.8, angle_deg=angle)
    if name == "sharpened":
        return unsharp_truth(angle_deg=angle, **USM)
    return kernel_truth(kernels[name], angle_deg=angle, psf_step_px=1 / S, supersample=S)


def _family_image(
    name: str, angle: float, snr: float, seed: int, kernels: dict[str, np.ndarray]
) -> np.ndarray:
    dark, bright = 51.0, 204.0
    kw = {
        "angle_deg": angle,
        "dark": dark,
        "bright": bright,
        "supersample": S,
        "offset_px": 0.137 * seed,
    }
    if name == "gauss 0.8":
        img = slanted_edge((100, 100), sigma_px=0.8, **kw)
    elif name == "sharpened":
        img = unsharp_mask(
            slanted_edge((100, 100), sigma_px=USM["sigma_px"], **kw),
            amount=USM["amount"],
            sigma_px=USM["mask_sigma_px"],
        )
    else:
        img = slanted_edge((100, 100), sigma_px=None, psf=kernels[name], psf_step_px=1 / S, **kw)
    if math.isfinite(snr):
        img = img + np.random.default_rng(seed).normal(0.0, (bright - dark) / snr, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def run_families(repeats: int = 3) -> list[float]:
    """The issue-16 table: four blur families x SNR {inf, 100, 50, 30}, 8-bit."""
    k = _kernels()
    kernels = {"halo 15%": 0.85 * k["_g0.6"] + 0.15 * k["_g2.0"], "defocus R2": k["disk R2"]}
    names = ("gauss 0.8", "halo 15%", "defocus R2", "sharpened")
    print()
    print(
        "blur families, 8-bit 100 x 100 ROIs, angles 5/12/20 deg x "
        f"{repeats} seeds; |error| median / worst; share within target"
    )
    head = (
        f"{'family':>10} {'SNR':>4} | {'primary':>9} | {'FWHM med%':>9} {'max%':>5} "
        f"{'<=2%':>5} | {'RER med':>7} {'max':>6} {'<=.02':>5} | {'MTF med':>7} {'max':>6} "
        f"{'ok':>5} | {'s/ROI':>5}"
    )
    print(head)
    print("-" * len(head))
    times: list[float] = []
    for name in names:
        for snr in FAMILY_SNRS:
            fw, rr, mt, prim, dt = [], [], [], [], []
            n = 0
            for angle in FAMILY_ANGLES:
                truth = _family_truth(name, angle, kernels)
                for seed in range(repeats):
                    img = _family_image(name, angle, snr, seed, kernels)
                    t0 = time.process_time()
                    r = measure_edge(img, limits=EdgeLimits(min_snr=25))
                    dt.append(time.process_time() - t0)
                    n += 1
                    if not r.valid:
                        continue
                    prim.append(CODE.get(r.primary_fit, "?"))
                    fw.append(abs(r.fwhm_px / truth.fwhm_px - 1))
                    rr.append(abs(r.rer - truth.rer))
                    mt.append(abs(r.mtf_nyquist - truth.mtf_nyquist))
            times += dt
            tol = 0.005 if math.isinf(snr) else 0.01
            if not fw:
                print(f"{name:>10} {snr:4.0f} | (no valid ROI of {n})")
                continue
            print(
                f"{name:>10} {snr:4.0f} | {''.join(prim):>9} | "
                f"{100 * statistics.median(fw):9.2f} {100 * max(fw):5.2f} "
                f"{sum(e <= 0.02 for e in fw):>2}/{n:<2} | "
                f"{statistics.median(rr):7.4f} {max(rr):6.4f} {sum(e <= 0.02 for e in rr):>2}/{n:<2} | "
                f"{statistics.median(mt):7.4f} {max(mt):6.4f} {sum(e <= tol for e in mt):>2}/{n:<2} | "
                f"{statistics.fmean(dt):5.3f}"
            )
    print("-" * len(head))
    print(
        f"CPU time per ROI (families): mean {statistics.fmean(times):.3f} s, median "
        f"{statistics.median(times):.3f} s, max {max(times):.3f} s (target < 0.3 s)"
    )
    return times


# ---------------------------------------------------------------------------------------------
# Issue 31: seven PSF families x SNR, refusals, uncertainty coverage, against MTF Mapper

FAMILIES31 = {  # two systems per family (alternating over the ROIs)
    "gauss": (PsfFamily("gauss", sigma=0.45), PsfFamily("gauss", sigma=0.8)),
    "halo": (
        PsfFamily("halo", sigma=0.5, sigma2=2.0, weight=0.15),
        PsfFamily("halo", sigma=0.55, sigma2=4.0, weight=0.1),
    ),
    "defocus": (
        PsfFamily("defocus", radius=1.5, sigma=0.4),
        PsfFamily("defocus", radius=2.0, sigma=0.5),
    ),
    "motion-across": (
        PsfFamily("motion_x", length=1.5, sigma=0.45),
        PsfFamily("motion_x", length=2.5, sigma=0.4),
    ),
    "motion-along": (
        PsfFamily("motion_y", length=1.5, sigma=0.45),
        PsfFamily("motion_y", length=3.0, sigma=0.4),
    ),
    "mtfc": (PsfFamily("mtfc", sigma=0.8, amount=0.25), PsfFamily("mtfc", sigma=0.6, amount=0.15)),
    "diffraction": (
        PsfFamily("diffraction", cutoff=1.0, sigma=0.25, length=0.8),
        PsfFamily("diffraction", cutoff=0.8, sigma=0.3, length=1.0),
    ),
}
# 2.5-40 deg, with the slopes 1/4, 1/3 and 1/2 (the old bin-occupancy check refused them)
ANGLES31 = (
    2.5,
    5.0,
    9.0,
    math.degrees(math.atan(0.25)),
    math.degrees(math.atan(1 / 3)),
    math.degrees(math.atan(0.5)),
    33.0,
    40.0,
)
SHAPES31 = ((60, 60), (100, 100), (200, 120))  # (lines, px across)
SNRS31 = (math.inf, 100.0, 50.0, 30.0)


@dataclass(frozen=True)
class Roi31:
    family: str
    psf: PsfFamily
    snr: float
    angle: float
    bits: int
    shape: tuple[int, int]
    seed: int

    def image(self, truth: FamilyTruth) -> np.ndarray:
        dark, bright = (40.0, 200.0) if self.bits == 8 else (600.0, 3000.0)
        return family_edge(
            self.psf,
            self.shape,
            angle_deg=self.angle,
            dark=dark,
            bright=bright,
            snr=self.snr,
            bit_depth=self.bits,
            offset_px=0.137 * self.seed,
            rng=np.random.default_rng(1000 + self.seed),
            truth=truth,
        )


def grid31(families: list[str] | None = None) -> list[Roi31]:
    """16 ROIs per family x SNR: 8 angles x the family's two systems, 8 and 12 bit alternating,
    60 x 60, 100 x 100 and 200 x 120 px in turn; 448 ROIs in all."""
    out = []
    for name, variants in FAMILIES31.items():
        if families and name not in families:
            continue
        for snr in SNRS31:
            for i, angle in enumerate(ANGLES31):
                for j, psf in enumerate(variants):
                    out.append(
                        Roi31(
                            name,
                            psf,
                            snr,
                            angle,
                            8 if (i + j) % 2 == 0 else 12,
                            SHAPES31[(i + 2 * j) % 3],
                            2 * i + j,
                        )
                    )
    return out


def _mtf_mapper(path: str | None) -> tuple[str | None, str]:
    exe = path or os.environ.get("MTF_MAPPER") or shutil.which("mtf_mapper")
    if not exe or not Path(exe).exists():
        return None, "not found (give --mtf-mapper PATH or set MTF_MAPPER)"
    out = subprocess.run([exe, "--version"], capture_output=True, text=True, check=False).stdout
    m = re.search(r"version:\s*([0-9.]+)", out)
    return exe, (m.group(1) if m else "unknown version")


def _write_tif(path: Path, img: np.ndarray) -> None:
    import rasterio
    from rasterio.errors import NotGeoreferencedWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(
            path,
            "w",
            driver="GTiff",
            width=img.shape[1],
            height=img.shape[0],
            count=1,
            dtype=img.dtype.name,
        ) as ds:
            ds.write(img, 1)


def _run_mtf_mapper(exe: str, img_path: Path, bits: int, work: Path) -> tuple[float | None, float]:
    """MTF@Nyquist by MTF Mapper on the whole image as one ROI, and the call's wall time (s).

    ``--single-roi -f``: raw_sfr_values.txt holds the edge angle and the SFR at 64 frequencies
    i/64 cycles/px (along the edge normal, pixel aperture included, as ours); 0.5 cycles/px is
    sample 32. ``-l``: the 8-bit data are linear (no sRGB decoding). None when it reports no
    edge (a refusal)."""
    out = work / "mm"
    if out.exists():
        shutil.rmtree(out)
    out.mkdir()
    cmd = [exe, "--single-roi", "-f", *(["-l"] if bits == 8 else []), str(img_path), str(out)]
    t0 = time.perf_counter()
    subprocess.run(cmd, capture_output=True, check=False)
    wall = time.perf_counter() - t0
    sfr = out / "raw_sfr_values.txt"
    rows = [ln.split() for ln in sfr.read_text().splitlines() if ln.strip()] if sfr.exists() else []
    if not rows or len(rows[0]) < 1 + 33:
        return None, wall
    return float(rows[0][1 + 32]), wall


def run31(args: argparse.Namespace) -> int:
    rois = grid31(args.family or None)
    exe, mm_version = _mtf_mapper(args.mtf_mapper)
    print(
        f"issue 31 grid: {len(rois)} ROIs (7 PSF families x SNR inf/100/50/30 x 16: angles 2.5-40 deg "
        "incl. slopes 1/4, 1/3, 1/2; 8/12 bit; 60-200 px), truth: synthetic.family_truth (2-D OTF, "
        "Fourier slice); orthospec with the SNR health check at 25 (the seed's 50 would refuse "
        "half of the SNR-50 ROIs by design)"
    )
    print(f"MTF Mapper: {exe or '-'} {mm_version}; load before: {_load()}")
    truths: dict[tuple[PsfFamily, float], FamilyTruth] = {}
    rec: dict[tuple[str, float], list[dict[str, Any]]] = {}
    lim = EdgeLimits(min_snr=25)
    cpu_lib: list[float] = []
    wall_mm: list[float] = []
    with tempfile.TemporaryDirectory(prefix="edge31-") as tmp:
        work = Path(tmp)
        for k, roi in enumerate(rois):
            key = (roi.psf, roi.angle)
            if key not in truths:
                truths[key] = family_truth(roi.psf, angle_deg=roi.angle)
            tr = truths[key]
            img = roi.image(tr)
            t0 = time.process_time()
            r = measure_edge(img, limits=lim)
            cpu_lib.append(time.process_time() - t0)
            row: dict[str, Any] = {"valid": r.valid}
            if r.valid:
                for name, truth in (("fwhm", tr.fwhm_px), ("rer", tr.rer), ("mtf", tr.mtf_nyquist)):
                    est = r.estimate({"fwhm": "fwhm_px", "mtf": "mtf_nyquist"}.get(name, name))
                    row[name] = est.value - truth
                    row[f"{name}_rel"] = est.value / truth - 1
                    row[f"{name}_u"] = est.u if est.u is not None else math.nan
            if exe:
                path = work / f"roi{k}.tif"
                _write_tif(path, img)
                mm, wall = _run_mtf_mapper(exe, path, roi.bits, work)
                wall_mm.append(wall)
                row["mm"] = None if mm is None else mm - tr.mtf_nyquist
            rec.setdefault((roi.family, roi.snr), []).append(row)
        timing = _command_times(rois, truths, exe, work, args) if args.command_rois else None
    return _report31(rec, cpu_lib, wall_mm, timing, bool(exe))


def _report31(
    rec: dict[tuple[str, float], list[dict[str, Any]]],
    cpu_lib: list[float],
    wall_mm: list[float],
    timing: dict[str, float] | None,
    have_mm: bool,
) -> int:
    print()
    head = (
        f"{'family':>13} {'SNR':>4} | {'n':>3} {'refused':>7} | {'FWHM2%':>6} {'RER.02':>6} "
        f"{'MTF.01':>6} {'all3':>5} | {'MM MTF.01':>9} {'MM ref':>6} | "
        f"{'cover 2u FWHM/RER/MTF':>21}"
    )
    print(head)
    print("-" * len(head))
    tot: dict[str, Any] = {}
    for (fam, snr), rows in rec.items():
        ok = [r for r in rows if r["valid"]]
        n = len(rows)
        fw = sum(abs(r["fwhm_rel"]) <= 0.02 for r in ok)
        rr = sum(abs(r["rer"]) <= 0.02 for r in ok)
        mt = sum(abs(r["mtf"]) <= 0.01 for r in ok)
        al = sum(
            abs(r["fwhm_rel"]) <= 0.02 and abs(r["rer"]) <= 0.02 and abs(r["mtf"]) <= 0.01
            for r in ok
        )
        mm_ok = sum(r.get("mm") is not None and abs(r["mm"]) <= 0.01 for r in rows)
        mm_ref = sum("mm" in r and r["mm"] is None for r in rows)
        cov = [sum(abs(r[m]) <= 2 * r[f"{m}_u"] for r in ok) for m in ("fwhm", "rer", "mtf")]
        print(
            f"{fam:>13} {snr:4.0f} | {n:3d} {n - len(ok):7d} | {fw:6d} {rr:6d} {mt:6d} {al:5d} | "
            f"{(str(mm_ok) if have_mm else '-'):>9} {(str(mm_ref) if have_mm else '-'):>6} | "
            f"{'/'.join(map(str, cov)):>21}"
        )
        t = tot.setdefault(
            snr,
            {
                "n": 0,
                "ng": 0,
                "ref": 0,
                "all_ng": 0,
                "fw_ng": 0,
                "fw": 0,
                "mt": 0,
                "mm": 0,
                "cov": [0, 0, 0],
                "valid": 0,
            },
        )
        t["n"] += n
        t["ref"] += n - len(ok)
        t["valid"] += len(ok)
        t["mt"] += mt
        t["mm"] += mm_ok
        t["fw"] += fw
        t["cov"] = [a + b for a, b in zip(t["cov"], cov, strict=True)]
        if fam != "gauss":
            t["ng"] += n
            t["all_ng"] += al
            t["fw_ng"] += fw
    print("-" * len(head))
    print("targets (issue 31):")
    for snr, t in tot.items():
        line = (
            f"  SNR {snr:>4.0f}: refused {t['ref']}/{t['n']}; non-Gaussian within all three "
            f"{t['all_ng']}/{t['ng']} ({100 * t['all_ng'] / max(t['ng'], 1):.1f} %), within FWHM 2 % "
            f"{t['fw_ng']}/{t['ng']} ({100 * t['fw_ng'] / max(t['ng'], 1):.1f} %); MTF@Ny within 0.01: "
            f"orthospec {t['mt']}/{t['n']}"
            + (f", MTF Mapper {t['mm']}/{t['n']}" if have_mm else "")
        )
        print(line)
    print(
        "  targets: no refusal at SNR >= 50; SNR 100 >= 95 % of non-Gaussian within all three; "
        "SNR 50 >= 85 % within FWHM 2 %; MTF@Ny within 0.01 at least as often as MTF Mapper"
    )
    fam_cov: dict[str, list[int]] = {}
    for (fam, _snr), rows in rec.items():
        ok = [r for r in rows if r["valid"]]
        c = fam_cov.setdefault(fam, [0, 0, 0, 0])
        c[3] += len(ok)
        for i, m in enumerate(("fwhm", "rer", "mtf")):
            c[i] += sum(abs(r[m]) <= 2 * r[f"{m}_u"] for r in ok)
    print("uncertainty coverage per family, |error| <= 2u over the four SNRs (FWHM / RER / MTF@Ny):")
    for fam, c in fam_cov.items():
        print(
            f"  {fam:>13}: "
            + " / ".join(f"{c[i]}/{c[3]} ({100 * c[i] / max(c[3], 1):.0f} %)" for i in range(3))
        )
    cov = [sum(t["cov"][i] for t in tot.values()) for i in range(3)]
    nv = sum(t["valid"] for t in tot.values())
    print(
        f"uncertainty coverage, |error| <= 2u (nominal 95 %): FWHM {cov[0]}/{nv} "
        f"({100 * cov[0] / max(nv, 1):.1f} %), RER {cov[1]}/{nv} ({100 * cov[1] / max(nv, 1):.1f} %), "
        f"MTF@Ny {cov[2]}/{nv} ({100 * cov[2] / max(nv, 1):.1f} %)"
    )
    print(
        f"library CPU per ROI: mean {statistics.fmean(cpu_lib):.3f} s, median "
        f"{statistics.median(cpu_lib):.3f} s, max {max(cpu_lib):.3f} s"
    )
    if wall_mm:
        print(
            f"MTF Mapper wall per ROI (one call per ROI, start-up included): mean "
            f"{statistics.fmean(wall_mm):.3f} s, median {statistics.median(wall_mm):.3f} s"
        )
    if timing:
        for k, v in timing.items():
            print(
                f"  {k}: {v:.3f}{'x' if k.startswith('ratio') else '' if k.startswith('ROIs') else ' s'}"
            )
    print(f"load after: {_load()}")
    return 0


def _command_times(
    rois: list[Roi31],
    truths: dict[tuple[PsfFamily, float], FamilyTruth],
    exe: str | None,
    work: Path,
    args: argparse.Namespace,
) -> dict[str, float]:
    """Whole commands, start-up included, in the same run: ``orthospec measure edge`` with one
    ROI per call and with all of them in one call (``--roi`` repeated, ``--workers``), against
    one MTF Mapper call per ROI, on the same ROIs (8-bit ones of 100 x 100 px, tiled)."""
    pick = [r for r in rois if r.bits == 8 and r.shape == (100, 100)][: args.command_rois]
    imgs = [r.image(truths[(r.psf, r.angle)]) for r in pick]
    mosaic = np.full((100, 110 * len(imgs)), 120, dtype=np.uint8)
    wins = []
    for i, im in enumerate(imgs):
        mosaic[:, 110 * i : 110 * i + 100] = im
        wins.append(f"{110 * i},0,{110 * i + 100},100")
    tile = work / "mosaic.tif"
    _write_tif(tile, mosaic)
    ortho = str(Path(sys.executable).with_name("orthospec"))
    out: dict[str, float] = {"ROIs timed as commands": float(len(imgs))}
    t0 = time.perf_counter()
    for w in wins:
        subprocess.run(
            [ortho, "measure", "edge", str(tile), "--roi", w, "--json"],
            capture_output=True,
            check=False,
        )
    out["orthospec measure edge, one ROI per call, wall per ROI"] = (
        time.perf_counter() - t0
    ) / len(wins)
    t0 = time.perf_counter()
    subprocess.run(
        [
            ortho,
            "measure",
            "edge",
            str(tile),
            *[a for w in wins for a in ("--roi", w)],
            "--workers",
            str(args.workers),
            "--json",
        ],
        capture_output=True,
        check=False,
    )
    out[
        f"orthospec measure edge, {len(wins)} ROIs in one call ({args.workers} workers), wall per ROI"
    ] = (time.perf_counter() - t0) / len(wins)
    if exe:
        paths = []
        for i, im in enumerate(imgs):
            paths.append(work / f"cmd{i}.tif")
            _write_tif(paths[-1], im)
        t0 = time.perf_counter()
        for p in paths:
            _run_mtf_mapper(exe, p, 8, work)
        out["MTF Mapper, one call per ROI, wall per ROI"] = (time.perf_counter() - t0) / len(imgs)
        k1 = "orthospec measure edge, one ROI per call, wall per ROI"
        kn = next(k for k in out if "in one call" in k)
        mm = out["MTF Mapper, one call per ROI, wall per ROI"]
        out["ratio orthospec (one per call) / MTF Mapper"] = out[k1] / mm
        out["ratio orthospec (all in one call) / MTF Mapper"] = out[kn] / mm
    return out


def _load() -> str:
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--legacy",
        action="store_true",
        help="the issue-15/16 tables (Gaussian grid, four blur families) instead of issue 31's",
    )
    ap.add_argument(
        "--family",
        action="append",
        choices=sorted(FAMILIES31),
        help="issue 31 grid: only these families (repeatable)",
    )
    ap.add_argument(
        "--mtf-mapper", help="MTF Mapper executable (default $MTF_MAPPER or mtf_mapper on PATH)"
    )
    ap.add_argument(
        "--command-rois", type=int, default=16, help="ROIs timed as whole commands (0: skip)"
    )
    ap.add_argument("--workers", type=int, default=2, help="workers of the many-ROI command")
    ap.add_argument("--size", type=int, default=100, help="ROI width (px across the edge)")
    ap.add_argument("--lines", type=int, default=100, help="ROI height (lines along the edge)")
    ap.add_argument("--repeats", type=int, default=5, help="noise seeds per configuration")
    ap.add_argument("--quick", action="store_true", help="3 angles instead of 5 for Gaussian PSFs")
    ap.add_argument("--families-only", action="store_true", help="only the blur-family table")
    args = ap.parse_args(argv)
    if not args.legacy:
        return run31(args)
    rc = 0 if args.families_only else run(args.size, args.lines, args.repeats, args.quick)
    run_families()
    return rc


if __name__ == "__main__":
    sys.exit(main())
