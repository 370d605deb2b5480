"""Accuracy of the cloud estimator (measures/signature.py) on a labelled set: synthetic clouds on a real scene.

Usage::

    .venv/bin/python benchmarks/cloud.py [--image ../shared/data/real/RGB.byte.tif] [--seeds 3]

For each cover in ``measures.cloudsim.COVERS`` and each seed, clouds are laid over the real Landsat
extract (measures/cloudsim.py), the scene is written as a GeoTIFF (nodata 0 on the pixels whose
truth is unknown: the collar, and the scene's own clouds and bright, white surfaces) and measured
by the same scan ``orthospec check`` runs (raster.reading.scan_raster). Printed: per scene the true
and measured cover (% of scored pixels), pixel accuracy, precision and recall; then the mean and
largest absolute cover error and the bias. tests/test_cloud_estimator.py holds the same numbers to
bounds.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / "shared" / "data" / "real" / "RGB.byte.tif"


def labelled_scores(
    image: Path, seeds: int = 3, workdir: Path | None = None
) -> list[tuple[float, int, object]]:
    """(cover, seed, Score) for every scene of the labelled set, measured through the scan."""
    import numpy as np
    import rasterio

    from orthospec.measures.cloudsim import COVERS, score, synthetic_clouds
    from orthospec.measures.signature import cloud_mask
    from orthospec.raster.reading import scan_raster

    with rasterio.open(image) as ds:
        base, profile = ds.read(), ds.profile
    out = []
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        for cover in COVERS:
            for seed in range(seeds):
                lab = synthetic_clouds(base, cover=cover, seed=1000 * seed + int(cover * 100))
                pixels = np.where(lab.scored[None], lab.pixels, 0).astype(np.uint8)
                path = Path(tmp) / f"c{cover}_{seed}.tif"
                with rasterio.open(path, "w", **{**profile, "nodata": 0}) as dst:
                    dst.write(pixels)
                measured = scan_raster(path).cloud_pct
                v = lab.pixels.astype(np.float32) / np.float32(255.0)
                mask = cloud_mask(v[0], v[1], v[2])
                out.append((cover, seed, score(lab, mask, measured)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--image", default=str(REAL))
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    if not Path(args.image).is_file():
        sys.exit(f"{args.image}: not found (../shared/data/real must be beside the checkout)")
    rows = labelled_scores(Path(args.image), args.seeds)
    print(
        f"{'cover':>6} {'seed':>4} {'true %':>8} {'measured %':>10} {'error':>7} {'accuracy':>8} "
        f"{'precision':>9} {'recall':>7}"
    )
    for cover, seed, s in rows:
        print(
            f"{cover:6.2f} {seed:4d} {s.true_pct:8.2f} {s.estimated_pct:10.2f} {s.error_pct:7.2f} "  # type: ignore[attr-defined]
            f"{s.accuracy:8.4f} {s.precision:9.3f} {s.recall:7.3f}"
        )  # type: ignore[attr-defined]
    errs = [s.error_pct for _, _, s in rows]  # type: ignore[attr-defined]
    upto20 = [s.error_pct for c, _, s in rows if c <= 0.20]  # type: ignore[attr-defined]
    print(
        f"scenes: {len(rows)}; cover error (measured - true, percentage points): mean |e| "
        f"{statistics.fmean(abs(e) for e in errs):.2f}, largest |e| {max(abs(e) for e in errs):.2f}, "
        f"bias {statistics.fmean(errs):+.2f}; up to 20 % cover: largest |e| {max(abs(e) for e in upto20):.2f}"
    )
    print(
        f"pixel accuracy: mean {statistics.fmean(s.accuracy for _, _, s in rows):.4f}; precision on scenes "  # type: ignore[attr-defined]
        f"with cloud: mean {statistics.fmean(s.precision for c, _, s in rows if c > 0):.3f}"
    )  # type: ignore[attr-defined]


if __name__ == "__main__":
    main()
