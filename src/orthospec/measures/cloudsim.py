"""A labelled set for the cloud estimator (measures/signature.py): synthetic clouds on a real scene. Pure.

``synthetic_clouds`` lays clouds over a real RGB scene (the Landsat extract in ``../shared/data/real``):
a smooth random field (Gaussian-filtered white noise) thresholded to the requested share gives
each pixel an opacity ``alpha`` that rises from 0 to 1 over a soft edge; the cloud's own colour is
a bright, slightly textured grey; the pixel becomes ``(1 - alpha) * ground + alpha * cloud``.
Truth: cloud where ``alpha >= 0.5`` (the edge's thin half is haze, not cloud).

The real scene has clouds of its own, which nobody labelled: ``unknown_truth`` marks them (and any
bright, white surface: bright sand, surf) generously, dilated by a few pixels, and those pixels
are not scored. The statement of accuracy says how many pixels were scored.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: opacity rises from 0 to 1 over this share of the field's spread above the threshold
EDGE = 0.25


@dataclass(frozen=True)
class Labelled:
    """One labelled scene: pixels (3, rows, cols, uint8), truth (bool), scored (bool)."""

    pixels: np.ndarray
    truth: np.ndarray
    scored: np.ndarray
    cover_pct: float  # true cloud share of the scored pixels


def _smooth_field(shape: tuple[int, int], scale: float, rng: np.random.Generator) -> np.ndarray:
    from scipy.ndimage import gaussian_filter

    f = gaussian_filter(rng.standard_normal(shape), sigma=scale, mode="wrap")
    return (f - f.mean()) / (f.std() or 1.0)


def unknown_truth(rgb: np.ndarray, *, nodata: int = 0) -> np.ndarray:
    """Pixels whose truth is unknown: collar (nodata in every band), and the scene's own bright,
    white pixels (real clouds, sand, surf) dilated by 3 px. Deliberately generous."""
    from scipy.ndimage import binary_dilation

    v = rgb.astype(np.float32) / 255.0
    bright = v.mean(axis=0)
    spread = v.max(axis=0) - v.min(axis=0)
    own = (bright >= 0.35) & (spread <= 0.35 * np.maximum(bright, 1e-6))
    collar = (rgb == nodata).all(axis=0)
    return binary_dilation(own, iterations=3) | collar


def synthetic_clouds(rgb: np.ndarray, *, cover: float, seed: int, scale: float = 12.0) -> Labelled:
    """Clouds over ``cover`` (0-1) of the scored pixels of an 8-bit RGB scene (3, rows, cols)."""
    rng = np.random.default_rng(seed)
    _, h, w = rgb.shape
    unknown = unknown_truth(rgb)
    scored = ~unknown
    field = _smooth_field((h, w), scale, rng)
    if cover <= 0:
        alpha = np.zeros((h, w), dtype=np.float32)
    else:
        t = float(
            np.quantile(field[scored], 1.0 - cover)
        )  # alpha >= 0.5 over `cover` of the scored pixels
        alpha = np.clip((field - t) / (EDGE * 2) + 0.5, 0.0, 1.0).astype(np.float32)
    texture = _smooth_field((h, w), 2.0, rng).astype(np.float32)
    cloud = (
        np.clip(232.0 + 12.0 * texture, 0, 255)[None, :, :]
        * np.array([1.0, 1.0, 1.02], np.float32)[:, None, None]
    )
    out = (1.0 - alpha) * rgb.astype(np.float32) + alpha * np.clip(cloud, 0, 255)
    out = np.where((rgb == 0).all(axis=0)[None], 0, np.clip(np.rint(out), 1, 255)).astype(np.uint8)
    truth = alpha >= 0.5
    return Labelled(
        pixels=out,
        truth=truth,
        scored=scored,
        cover_pct=100.0 * float(truth[scored].mean()) if scored.any() else 0.0,
    )


@dataclass(frozen=True)
class Score:
    """The estimator against one labelled scene: cover (% of scored pixels) and per-pixel agreement."""

    true_pct: float
    estimated_pct: float
    accuracy: float  # share of scored pixels classified right
    precision: float  # of the pixels called cloud, the share that are
    recall: float  # of the cloud pixels, the share called cloud

    @property
    def error_pct(self) -> float:
        return self.estimated_pct - self.true_pct


def score(labelled: Labelled, estimated: np.ndarray, estimated_pct: float | None = None) -> Score:
    """Score a per-pixel cloud mask (and, when given, the cover the scan measured) on the scored pixels."""
    t, e = labelled.truth[labelled.scored], estimated[labelled.scored]
    tp = float(np.count_nonzero(t & e))
    pct = 100.0 * float(e.mean()) if estimated_pct is None else float(estimated_pct)
    return Score(
        true_pct=labelled.cover_pct,
        estimated_pct=pct,
        accuracy=float((t == e).mean()),
        precision=tp / max(float(np.count_nonzero(e)), 1.0),
        recall=tp / max(float(np.count_nonzero(t)), 1.0),
    )


#: the labelled set: (cover, seed) of each synthetic scene
COVERS = (0.0, 0.01, 0.02, 0.05, 0.08, 0.10, 0.15, 0.20, 0.30, 0.50)
