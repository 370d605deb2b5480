"""Benchmark: accuracy and time of the edge chain over angles, PSFs and noise levels.

Usage::

    .venv/bin/python benchmarks/edge.py [--size 100] [--lines 100] [--repeats 5]

For every (angle, Gaussian sigma, SNR) it renders ``--repeats`` synthetic slanted edges
(``orthospec.measures.synthetic``, different noise seeds and sub-pixel offsets), runs
``measure_edge`` and prints, against the analytic truth of Gaussian PSF * square pixel:
the mean and worst FWHM error (%), the worst MTF@Nyquist, RER and angle errors, the share
of valid ROIs and the mean time per ROI (measurement only, not rendering). Target: < 0.5 s
per 100 x 100 ROI. Deterministic input (seeded); timings depend on the machine.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from orthospec.measures.edge import measure_edge
from orthospec.measures.synthetic import edge_truth, slanted_edge

ANGLES = (2.0, 5.0, 10.0, 20.0, 29.0)
SIGMAS = (0.4, 0.8, 1.5)
SNRS = (60.0, 100.0, 500.0)


def run(size: int, lines: int, repeats: int) -> int:
    print(f"edge chain: {lines} lines x {size} px ROIs, {repeats} seeds per row; errors vs truth")
    head = (f"{'angle':>5} {'sigma':>5} {'SNR':>5} | {'valid':>5} | {'FWHM mean%':>10} "
            f"{'FWHM max%':>9} | {'MTF max':>7} | {'RER max':>7} | {'ang max':>7} | {'s/ROI':>6}")
    print(head)
    print("-" * len(head))
    times: list[float] = []
    worst = {"fwhm": 0.0, "mtf": 0.0, "rer": 0.0, "angle": 0.0}
    for snr in SNRS:
        for sigma in SIGMAS:
            for angle in ANGLES:
                truth = edge_truth(sigma_px=sigma, angle_deg=angle)
                fw, mt, rr, an, dt = [], [], [], [], []
                for seed in range(repeats):
                    img = slanted_edge((lines, size), angle_deg=angle, sigma_px=sigma, snr=snr,
                                       supersample=9, offset_px=0.137 * seed,
                                       rng=np.random.default_rng(seed))
                    t0 = time.perf_counter()
                    r = measure_edge(img)
                    dt.append(time.perf_counter() - t0)
                    if not r.valid:
                        continue
                    fw.append(r.fwhm_px / truth.fwhm_px - 1)
                    mt.append(abs(r.mtf_nyquist - truth.mtf_nyquist))
                    rr.append(abs(r.rer - truth.rer))
                    an.append(abs(r.angle_deg - angle))
                times += dt
                if fw:
                    worst["fwhm"] = max(worst["fwhm"], max(map(abs, fw)))
                    worst["mtf"] = max(worst["mtf"], max(mt))
                    worst["rer"] = max(worst["rer"], max(rr))
                    worst["angle"] = max(worst["angle"], max(an))
                    print(f"{angle:5.1f} {sigma:5.2f} {snr:5.0f} | {len(fw):2d}/{repeats:<2d} | "
                          f"{100 * statistics.fmean(fw):+10.2f} {100 * max(map(abs, fw)):9.2f} | "
                          f"{max(mt):7.4f} | {max(rr):7.4f} | {max(an):7.3f} | "
                          f"{statistics.fmean(dt):6.3f}")
                else:
                    print(f"{angle:5.1f} {sigma:5.2f} {snr:5.0f} |  0/{repeats:<2d} | (no valid ROI)"
                          f"{'':>40} {statistics.fmean(dt):6.3f}")
    print("-" * len(head))
    print(f"time per ROI: mean {statistics.fmean(times):.3f} s, median "
          f"{statistics.median(times):.3f} s, max {max(times):.3f} s (target < 0.5 s)")
    print(f"worst errors: FWHM {100 * worst['fwhm']:.2f} %, MTF@Ny {worst['mtf']:.4f}, "
          f"RER {worst['rer']:.4f}, angle {worst['angle']:.3f} deg")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=100, help="ROI width (px across the edge)")
    ap.add_argument("--lines", type=int, default=100, help="ROI height (lines along the edge)")
    ap.add_argument("--repeats", type=int, default=5, help="noise seeds per configuration")
    args = ap.parse_args(argv)
    return run(args.size, args.lines, args.repeats)


if __name__ == "__main__":
    sys.exit(main())
