"""Subpixel area-based matching of a reference chip on an orthoimage (JRC §12.6 check points).

Pure numeric layer (numpy, scipy, scikit-image; no file I/O): the reader
(``orthospec.raster.chips``) resamples the reference into the delivered image's pixel grid and
hands over two luminance arrays on that one grid, a *template* (the reference around the point,
``t x t``) and a *search* window of the image (``t + 2 s`` square, the point at its centre).
:func:`match_chip` finds where the template's content lies in the search window and says whether
the match can be trusted; a match it cannot vouch for goes to the checker, with the reason, never
through as a number.

How a position is found:

1. integer position: normalised cross-correlation of the template over the search window
   (``skimage.feature.match_template``), its peak and the next-best distinct peak;
2. subpixel refinement, one of two estimators (``MatchSettings.method``):

   * ``phase``: phase correlation with upsampled DFT (``skimage.registration.phase_cross_correlation``)
     of the template and the image patch at the current estimate, both under a Hann window, iterated
     on the patch resampled (cubic spline) at the new estimate until the correction is below
     1/1000 px: the common window's pull towards zero vanishes at convergence;
   * ``ncc``: a separable three-point Gaussian fit (parabolic where the correlation is not positive)
     to the correlation peak.

   The other estimator is computed too and the two must agree (``max_disagreement_px``);
3. quality: the correlation of the template with the patch resampled at the final position, the
   ratio of the correlation peak to the next-best distinct peak, and the precision the least-squares
   model predicts for the position (Förstner: ``sigma / (|gain| sqrt(lambda_min))``, residual sigma of
   ``patch = gain * template + offset`` over the smaller eigenvalue of the template's gradient
   structure tensor), which grows with noise, radiometric change and weak or one-directional texture.

Decisions (``Match.reason_code``): ``edge`` (search window leaves the image or meets no-data),
``low_texture`` (the reference has no texture above its noise in one direction or both),
``cloud`` (texture of the reference missing in a bright part of the image), ``change`` (image and
reference differ: low correlation or a poor predicted precision), ``ambiguous`` (a second peak nearly
as high), ``search_limit`` (the best position is on the border of the search range), ``unstable``
(the two subpixel estimators disagree). The thresholds come from ``benchmarks/matching.py``, where
every one of them is exercised on synthetic truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

__all__ = [
    "METHODS",
    "Match",
    "MatchSettings",
    "luminance",
    "match_chip",
    "noise_sigma",
    "texture_ratio",
]

#: subpixel estimators (the first is the default, chosen by ``benchmarks/matching.py``)
METHODS: tuple[str, ...] = ("phase", "ncc")

#: :func:`texture_ratio` of pure noise is 1; sharp, textured 8-bit imagery (Landsat, 300 m) scores
#: 2.2 to 31 (Immerkær's estimator takes pixel-scale texture for noise): below this, a chip is flat
FLAT_TEXTURE = 1.5

#: reason code -> the sentence the checker reads on the hand list
REASONS: dict[str, str] = {
    "edge": "edge of image: the search window leaves the image or meets no-data",
    "low_texture": "low texture: the reference has too little contrast to locate the point",
    "cloud": "cloud: the reference's texture is missing under a bright, flat area of the image",
    "change": "change: the image differs from the reference around the point",
    "ambiguous": "ambiguous: a second position matches almost as well",
    "search_limit": "search limit: the best position lies on the border of the search range",
    "unstable": "unstable: the subpixel estimators disagree",
}


@dataclass(frozen=True)
class MatchSettings:
    """How a chip is matched and when a match is accepted (defaults measured in the benchmark)."""

    method: Literal["phase", "ncc"] = "phase"
    #: largest shift searched, in image pixels, either way along each axis
    search_px: int = 16
    #: upsampling of the phase correlation's DFT (1/upsample px resolution)
    upsample: int = 100
    #: smallest accepted correlation of the template with the image at the match
    min_score: float = 0.6
    #: smallest accepted ratio of the correlation peak to the next-best distinct peak
    min_peak_ratio: float = 1.25
    #: largest accepted predicted precision (1 sigma) of the position, px
    max_sigma_px: float = 0.08
    #: smallest ratio of the template's weakest gradient energy to that of its noise
    min_texture: float = FLAT_TEXTURE
    #: a rejected match is put down to low texture when the template's standard deviation is
    #: below this many noise sigmas (else to change)
    low_contrast: float = 2.0
    #: share of the template whose texture is missing in the image above which the image is obscured:
    #: in benchmarks/matching.py (100 pairs per family) no accepted textured pair exceeded 0.03, while
    #: 2 of 100 cloud pairs (a third of the template under cloud) measured 0.12 and 0.15 and were
    #: accepted at the former 0.15
    max_obscured: float = 0.08
    #: largest accepted disagreement of the two subpixel estimators, px
    max_disagreement_px: float = 0.35
    #: smallest template side, px
    min_template_px: int = 16

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(
                f"unknown matching method {self.method!r}; expected one of {', '.join(METHODS)}"
            )
        if self.search_px < 1 or self.upsample < 1 or self.min_template_px < 8:
            raise ValueError("search_px and upsample must be >= 1, min_template_px >= 8")


@dataclass(frozen=True)
class Match:
    """Where the template's content lies in the image, relative to where the reference puts it.

    ``dx_px`` / ``dy_px`` are image columns / rows (positive: right / down); NaN when no position
    was estimated. ``decision`` is ``accepted`` or ``by_hand``; ``reason`` says why in words.
    """

    dx_px: float
    dy_px: float
    score: float
    peak_ratio: float
    sigma_px: float
    texture: float
    obscured: float
    decision: str
    reason_code: str = ""
    reason: str = ""
    other_dx_px: float = math.nan
    other_dy_px: float = math.nan
    details: dict[str, float] = field(default_factory=dict, compare=False)

    @property
    def accepted(self) -> bool:
        return self.decision == "accepted"


def luminance(bands: np.ndarray) -> np.ndarray:
    """Mean of the bands (``(n, h, w)`` or ``(h, w)``) as float64: the common ground of two images
    whose bands differ in weight (season, sensor) but not in geometry."""
    a = np.asarray(bands, dtype=np.float64)
    return a if a.ndim == 2 else a.mean(axis=0)


def noise_sigma(img: np.ndarray) -> float:
    """Gaussian noise sigma of an image, Immerkær's estimator (1996): the mean absolute response
    of the Laplacian difference mask, which cancels locally linear content."""
    a = np.asarray(img, dtype=np.float64)
    h, w = a.shape
    if h < 3 or w < 3:
        return math.nan
    r = (
        a[:-2, :-2]
        - 2 * a[:-2, 1:-1]
        + a[:-2, 2:]
        - 2 * a[1:-1, :-2]
        + 4 * a[1:-1, 1:-1]
        - 2 * a[1:-1, 2:]
        + a[2:, :-2]
        - 2 * a[2:, 1:-1]
        + a[2:, 2:]
    )
    return float(math.sqrt(math.pi / 2) * np.abs(r).mean() / 6.0)


def _structure(t: np.ndarray) -> tuple[float, float]:
    """(lambda_min, lambda_max) of the gradient structure tensor summed over the template."""
    gy, gx = np.gradient(t)
    sxx, syy, sxy = float((gx * gx).sum()), float((gy * gy).sum()), float((gx * gy).sum())
    tr, det = sxx + syy, sxx * syy - sxy * sxy
    disc = math.sqrt(max(tr * tr / 4 - det, 0.0))
    return max(tr / 2 - disc, 0.0), tr / 2 + disc


def texture_ratio(t: np.ndarray) -> float:
    """Weakest-direction gradient energy per pixel over what noise alone gives (sigma**2 / 2 for a
    central difference): about 1 for a flat chip, large for a textured one."""
    sigma = noise_sigma(t)
    lam_min, _ = _structure(t)
    per_px = lam_min / t.size
    floor = max(sigma * sigma / 2, 1e-12)
    return float(per_px / floor)


def _hann(n: int) -> np.ndarray:
    w = np.hanning(n + 2)[1:-1]
    return np.outer(w, w)


#: pixels taken around a patch before its Fourier shift (the periodic wrap stays outside the crop)
_FOURIER_PAD = 8


def _patch(search: np.ndarray, top: float, left: float, t: int) -> np.ndarray:
    """The ``t x t`` patch of ``search`` whose top-left corner is at (top, left).

    A fractional position is resampled by the Fourier shift theorem (sinc interpolation) over the
    patch plus a border, then cropped: polynomial kernels (cubic spline, cubic convolution) delay
    the fine texture of a sharp image by a fraction-dependent amount, and iterating on patches
    resampled with them converged 0.01-0.05 px off (benchmarks/matching.py)."""
    i, j = math.floor(top), math.floor(left)
    fi, fj = top - i, left - j
    if fi == 0 and fj == 0 and i >= 0 and j >= 0:
        return search[i : i + t, j : j + t]
    from scipy.ndimage import fourier_shift

    p = _FOURIER_PAD
    padded = np.pad(search, p + 1, mode="reflect")
    i0, j0 = i + 1, j + 1  # position in padded, minus the border p
    region = padded[i0 : i0 + t + 2 * p, j0 : j0 + t + 2 * p]
    moved = np.fft.ifft2(fourier_shift(np.fft.fft2(region), (-fi, -fj))).real
    return moved[p : p + t, p : p + t]


def _gauss_or_parabola(m1: float, c0: float, p1: float) -> float:
    """Subpixel offset of a three-sample peak: Gaussian (log) fit when all positive, else parabola."""
    if m1 > 0 and c0 > 0 and p1 > 0:
        a, b, c = math.log(m1), math.log(c0), math.log(p1)
    else:
        a, b, c = m1, c0, p1
    den = a - 2 * b + c
    if den >= 0:
        return 0.0
    return float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))


def _second_peak(surface: np.ndarray, at: tuple[int, int], exclude: int) -> float:
    """Highest local maximum of ``surface`` farther than ``exclude`` px from ``at``."""
    from scipy.ndimage import maximum_filter

    local = surface == maximum_filter(surface, size=3, mode="nearest")
    rr, cc = np.nonzero(local)
    far = np.maximum(np.abs(rr - at[0]), np.abs(cc - at[1])) > exclude
    return float(surface[rr[far], cc[far]].max()) if far.any() else -1.0


def _cross_power_peak(
    f_ref: np.ndarray, f_mov: np.ndarray, *, upsample: int, span_px: float
) -> tuple[float, float]:
    """Displacement (dy, dx) of ``moving`` relative to ``reference`` from their spectra: the peak of
    the cross-correlation, refined on a DFT upsampled ``upsample`` times over +-``span_px`` around
    it (Guizar-Sicairos et al. 2008, the algorithm of ``skimage.registration.phase_cross_correlation``
    with ``normalization=None``, through the BLAS-free DFT of :mod:`.radiometry`: complex BLAS
    products cost 25 ms each here, the real einsums well under 1 ms). Not phase-normalised:
    whitening the spectrum lifts the frequencies a coarser reference lacks and biased 1:2 pairs by
    0.17 px (benchmarks/matching.py)."""
    from .registration import _upsampled_dft

    product = f_ref * f_mov.conj()
    cc = np.fft.ifft2(product).real
    peak = np.unravel_index(int(np.argmax(cc)), cc.shape)
    shape = np.array(cc.shape)
    shifts = np.array(peak, dtype=np.float64)
    shifts[shifts > shape // 2] -= shape[shifts > shape // 2]
    if upsample > 1:
        shifts = np.round(shifts * upsample) / upsample
        region = max(3, math.ceil(upsample * 2 * span_px))
        centre = float(np.fix(region / 2.0))
        offsets = centre - shifts * upsample
        up = _upsampled_dft(
            product.conj(), region, upsample, (float(offsets[0]), float(offsets[1]))
        ).conj()
        m = np.unravel_index(int(np.argmax(up.real)), up.shape)
        shifts = shifts + (np.array(m, dtype=np.float64) - centre) / upsample
    return float(-shifts[0]), float(-shifts[1])


def _phase_refine(
    template: np.ndarray,
    search: np.ndarray,
    top: float,
    left: float,
    upsample: int,
    iterations: int = 5,
) -> tuple[float, float] | None:
    """Iterated :func:`_cross_power_peak` of the Hann-tapered template and image patch, the patch
    resampled at each new estimate: first to 1/10 px over +-0.75 px around the integer peak, then
    to 1/``upsample`` px over +-0.1 px, until the correction is below 1/1000 px. None when an
    estimate leaves the search window (the iteration diverged: seen on a repetitive texture with
    a large radiometric change, where it walked 17 px off the correlation peak and out)."""
    from .registration import tapered_spectrum

    t = template.shape[0]
    last = search.shape[0] - t  # the largest top/left whose patch lies inside the window
    f_t = tapered_spectrum(template)
    factor, span = min(10, upsample), 0.75
    for _ in range(iterations):
        dy, dx = _cross_power_peak(
            f_t, tapered_spectrum(_patch(search, top, left, t)), upsample=factor, span_px=span
        )
        top, left = top + dy, left + dx
        if not (0.0 <= top <= last and 0.0 <= left <= last):
            return None
        if factor == upsample and abs(dy) < 1e-3 and abs(dx) < 1e-3:
            break
        factor, span = upsample, 0.1
    return top, left


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    a = a - a.mean()
    b = b - b.mean()
    den = math.sqrt(float((a * a).sum()) * float((b * b).sum()))
    return float((a * b).sum() / den) if den > 0 else 0.0


def _obscured(template: np.ndarray, patch: np.ndarray, cell: int = 8) -> tuple[float, bool]:
    """Share of the template's textured cells whose texture the image patch lacks, and whether those
    cells are bright in the image (cloud, snow, haze) rather than merely different.

    A cell lacks texture when its standard deviation in the image is below 30 % of the
    template's scaled by the contrast ratio of the best-kept cells (75th percentile: a uniform
    gain or gamma change is not a loss); every cell does when the patch has no texture above its
    noise (a cloud as wide as the chip leaves nothing to take a ratio from).
    """
    t = template.shape[0]
    n = t // cell
    if n < 2:
        return 0.0, False

    def cells(a: np.ndarray) -> np.ndarray:
        return a[: n * cell, : n * cell].reshape(n, cell, n, cell).swapaxes(1, 2).reshape(n, n, -1)

    tt, pp = cells(template), cells(patch)
    ts, ps = tt.std(axis=2), pp.std(axis=2)
    textured = (ts >= 0.5 * float(np.median(ts))) & (ts > 2.5 * noise_sigma(template))
    if not textured.any():
        return 0.0, False
    if (
        texture_ratio(patch) < FLAT_TEXTURE
    ):  # a flat image: the reference's texture is missing everywhere
        missing = textured
    else:
        kept = float(np.percentile(ps[textured] / ts[textured], 75))
        missing = textured & (ps < 0.3 * kept * ts)
    share = float(missing.sum() / textured.sum())
    if not missing.any():
        return share, False
    # brighter than the rest of the image patch, or than the reference (a chip-wide cloud)
    level = float(pp[missing].mean())
    rest = ~missing
    bright = (bool(rest.any()) and level > float(pp[rest].mean())) or (
        level > float(template.mean()) + 0.5 * float(template.std())
    )
    return share, bright


def match_chip(
    template: np.ndarray,
    search: np.ndarray,
    *,
    search_valid: np.ndarray | None = None,
    settings: MatchSettings | None = None,
) -> Match:
    """Locate ``template`` (t x t, the reference on the image grid) in ``search`` ((t+2s) x (t+2s)).

    The template's nominal place is the centre of ``search`` (offset ``s`` both ways); the result's
    ``dx_px``/``dy_px`` is how far the content lies from there. ``search_valid`` marks the image
    pixels that exist (inside the image, not no-data); a window that is not entirely valid goes to
    the checker (``edge``).

    Raises
    ------
    ValueError
        when the shapes do not fit together (a caller's bug, not bad data).
    """
    s = settings or MatchSettings()
    template = np.asarray(template, dtype=np.float64)
    search = np.asarray(search, dtype=np.float64)
    t = template.shape[0]
    if (
        template.ndim != 2
        or template.shape[1] != t
        or search.ndim != 2
        or search.shape[0] != search.shape[1]
    ):
        raise ValueError(
            f"template {template.shape} and search {search.shape} must be square 2-D arrays"
        )
    margin = (search.shape[0] - t) // 2
    if search.shape[0] != t + 2 * margin or margin < 1:
        raise ValueError(
            f"search window {search.shape} must be the template {template.shape} plus an even margin"
        )
    if t < s.min_template_px:
        raise ValueError(
            f"template of {t} px is smaller than min_template_px = {s.min_template_px}"
        )
    nan = math.nan

    def by_hand(code: str, **kw: float) -> Match:
        base = {
            "dx_px": nan,
            "dy_px": nan,
            "score": nan,
            "peak_ratio": nan,
            "sigma_px": nan,
            "texture": nan,
            "obscured": nan,
        }
        base.update(kw)
        return Match(decision="by_hand", reason_code=code, reason=REASONS[code], **base)  # type: ignore[arg-type]

    if search_valid is not None and not bool(np.all(search_valid)):
        return by_hand("edge")
    if not (np.isfinite(template).all() and np.isfinite(search).all()):
        return by_hand("edge")
    texture = texture_ratio(template)
    if not texture >= s.min_texture:
        return by_hand("low_texture", texture=texture)

    from skimage.feature import match_template

    surface = match_template(search, template)  # (2*margin+1) square, NCC
    i0, j0 = np.unravel_index(int(np.argmax(surface)), surface.shape)
    peak = float(surface[i0, j0])
    second = _second_peak(surface, (int(i0), int(j0)), exclude=2)
    ratio = peak / max(second, 0.05) if peak > 0 else 0.0
    # texture the image lacks where the reference has it: cloud, or change
    obscured, bright = _obscured(template, _patch(search, float(i0), float(j0), t))
    if obscured > s.max_obscured:
        return by_hand(
            "cloud" if bright else "change",
            score=peak,
            peak_ratio=ratio,
            texture=texture,
            obscured=obscured,
        )
    if i0 in (0, surface.shape[0] - 1) or j0 in (0, surface.shape[1] - 1):
        return by_hand(
            "search_limit", score=peak, peak_ratio=ratio, texture=texture, obscured=obscured
        )
    # both subpixel estimators from the integer peak
    fi = _gauss_or_parabola(*(float(v) for v in surface[i0 - 1 : i0 + 2, j0]))
    fj = _gauss_or_parabola(*(float(v) for v in surface[i0, j0 - 1 : j0 + 2]))
    ncc_top, ncc_left = i0 + fi, j0 + fj
    # keep the refined patch inside the search window (a cubic spline needs one px beyond)
    refined = _phase_refine(template, search, float(i0), float(j0), s.upsample)
    if refined is None:  # the refinement left the window: the estimators cannot agree
        return by_hand("unstable", score=peak, peak_ratio=ratio, texture=texture, obscured=obscured)
    ph_top, ph_left = refined
    lim = 2 * margin - 1.0
    if not (1.0 <= ph_top <= lim and 1.0 <= ph_left <= lim):
        ph_top, ph_left = ncc_top, ncc_left
    top, left = (ph_top, ph_left) if s.method == "phase" else (ncc_top, ncc_left)
    o_top, o_left = (ncc_top, ncc_left) if s.method == "phase" else (ph_top, ph_left)
    patch = _patch(search, top, left, t)
    score = _corr(template, patch)
    # least-squares radiometric fit patch = gain * template + offset, its residual and the
    # predicted precision of the position
    tc = template - template.mean()
    gain = float((tc * (patch - patch.mean())).sum() / max(float((tc * tc).sum()), 1e-12))
    resid = patch - patch.mean() - gain * tc
    lam_min, _ = _structure(template)
    sigma_px = (
        float(resid.std() / (abs(gain) * math.sqrt(lam_min)))
        if gain != 0 and lam_min > 0
        else math.inf
    )
    kw = {
        "dx_px": left - margin,
        "dy_px": top - margin,
        "score": score,
        "peak_ratio": ratio,
        "sigma_px": sigma_px,
        "texture": texture,
        "obscured": obscured,
        "other_dx_px": o_left - margin,
        "other_dy_px": o_top - margin,
    }
    disagreement = math.hypot(top - o_top, left - o_left)
    details = {"gain": gain, "disagreement_px": disagreement}
    if score < s.min_score or not sigma_px <= s.max_sigma_px:
        code = (
            "low_texture"
            if float(template.std()) < s.low_contrast * noise_sigma(template)
            else "change"
        )
    elif ratio < s.min_peak_ratio:
        code = "ambiguous"
    elif disagreement > s.max_disagreement_px:
        code = "unstable"
    else:
        return Match(decision="accepted", details=details, **kw)
    return Match(decision="by_hand", reason_code=code, reason=REASONS[code], details=details, **kw)
