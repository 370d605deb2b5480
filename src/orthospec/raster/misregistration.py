"""Band misregistration of one image (JRC EUR 23638 EN §6.3): windows copied out of the scan's
chunks as they pass, phase-correlated band against band (measures/registration.py)."""

from __future__ import annotations

import threading
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import rasterio
from rasterio.windows import Window

from ..measures.registration import Shift, phase_correlation_spectra, tapered_spectrum
from .opening import BandInfo, validity

#: Sub-pixel resolution of the band misregistration, 1/20 px (1/10 px was 0.1 px off
#: on the synthetic 1.5 px test shift).
MISREGISTRATION_UPSAMPLE = 20


@dataclass
class MisregistrationWindows:
    """Band-to-band shift vs the green (else first) band: median over up to 5 square windows.

    The windows are copied out of the chunks of the one streaming read as they pass (no second
    read of the file); a window is phase-correlated by the counting thread that completes it,
    so that work overlaps the rest of the scan (the results are the same in any thread).
    """

    infos: Sequence[BandInfo]
    ref: int
    others: list[BandInfo]
    windows: list[Window]
    data: list[np.ndarray]
    masks: list[np.ndarray | None]
    filled: list[int] = field(default_factory=list)
    shifts: list[dict[int, Shift] | None] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)
    #: where completed windows are correlated (a thread of their own during a threaded scan);
    #: None: by the thread that completes them
    correlator: ThreadPoolExecutor | None = None
    pending: dict[int, Future[dict[int, Shift]]] = field(default_factory=dict)

    @classmethod
    def plan(
        cls, ds: rasterio.io.DatasetReader, infos: Sequence[BandInfo], *, size: int = 256
    ) -> MisregistrationWindows:
        colour = {b.colour: b.index for b in infos}
        ref = colour.get("green", 1)
        others = [b for b in infos if b.index != ref and b.colour != "alpha"]
        n = min(size, ds.height, ds.width)
        wins: list[Window] = []
        if n >= 32 and others:
            for fy, fx in ((0.5, 0.5), (0.25, 0.25), (0.25, 0.75), (0.75, 0.25), (0.75, 0.75)):
                row = int(min(max(fy * ds.height - n / 2, 0), ds.height - n))
                col = int(min(max(fx * ds.width - n / 2, 0), ds.width - n))
                w = Window(col, row, n, n)
                if w not in wins:
                    wins.append(w)
        use_mask = any(b.use_mask for b in infos)
        dtype = np.result_type(*ds.dtypes)
        return cls(
            infos=infos,
            ref=ref,
            others=others,
            windows=wins,
            data=[np.zeros((ds.count, n, n), dtype=dtype) for _ in wins],
            masks=[np.zeros((n, n), dtype=np.uint8) if use_mask else None for _ in wins],
            filled=[0] * len(wins),
            shifts=[None] * len(wins),
        )

    def take(self, win: Window, data: np.ndarray, mask: np.ndarray | None) -> None:
        """Copy the part of each window that this chunk (at ``win``) holds; correlate the
        windows this chunk completes (chunks are disjoint and cover the image)."""
        c0, r0 = int(win.col_off), int(win.row_off)
        c1, r1 = c0 + int(win.width), r0 + int(win.height)
        for i, (w, buf, mbuf) in enumerate(zip(self.windows, self.data, self.masks, strict=True)):
            wc0, wr0 = int(w.col_off), int(w.row_off)
            ic0, ic1 = max(c0, wc0), min(c1, wc0 + int(w.width))
            ir0, ir1 = max(r0, wr0), min(r1, wr0 + int(w.height))
            if ic0 >= ic1 or ir0 >= ir1:
                continue
            dst = (slice(ir0 - wr0, ir1 - wr0), slice(ic0 - wc0, ic1 - wc0))
            src = (slice(ir0 - r0, ir1 - r0), slice(ic0 - c0, ic1 - c0))
            buf[(slice(None), *dst)] = data[(slice(None), *src)]
            if mbuf is not None and mask is not None:
                mbuf[dst] = mask[src]
            with self.lock:
                self.filled[i] += (ir1 - ir0) * (ic1 - ic0)
                complete = self.filled[i] == int(w.width) * int(w.height)
            if complete:
                if self.correlator is not None:
                    # not in the counting thread: its next chunks (and, through the chunks in
                    # flight, the reader and the other counting thread) would wait ~16 ms
                    self.pending[i] = self.correlator.submit(self._correlate, i)
                else:
                    self.shifts[i] = self._correlate(i)

    def _correlate(self, i: int) -> dict[int, Shift]:
        """Shift of every other band vs the reference band in window ``i`` (none if too few
        valid pixels or a flat band)."""
        data, mask = self.data[i], self.masks[i]
        ref_info = self.infos[self.ref - 1]
        a = _filled(
            data[self.ref - 1],
            validity(data[self.ref - 1], ref_info, mask if ref_info.use_mask else None),
        )
        if a is None:
            return {}
        f_ref = tapered_spectrum(a)
        out = {}
        for b in self.others:
            m = _filled(
                data[b.index - 1], validity(data[b.index - 1], b, mask if b.use_mask else None)
            )
            if m is not None:
                out[b.index] = phase_correlation_spectra(
                    f_ref, tapered_spectrum(m), upsample=MISREGISTRATION_UPSAMPLE
                )
        return out

    def result(self) -> tuple[int, dict[int, Shift], dict[int, float]]:
        found: dict[int, list[Shift]] = {b.index: [] for b in self.others}
        for i in range(len(self.windows)):  # window order: the same medians in any thread
            if i in self.pending:
                self.shifts[i] = self.pending.pop(i).result()
            got = self.shifts[i]
            if got is None:  # not completed by the chunks (cannot happen; stay exact anyway)
                got = self.shifts[i] = self._correlate(i)
            for idx, shift in got.items():
                found[idx].append(shift)
        result, spreads = {}, {}
        for idx, shifts in found.items():
            if shifts:
                dy = float(np.median([s.dy for s in shifts]))
                dx = float(np.median([s.dx for s in shifts]))
                spreads[idx] = max(float(np.hypot(s.dy - dy, s.dx - dx)) for s in shifts)
                result[idx] = Shift(dy=dy, dx=dx, peak=float(np.median([s.peak for s in shifts])))
        return self.ref, result, spreads


#: A band shift is trusted only when the phase-correlation peak stands out and the windows agree:
#: bands that share little texture (NIR vs green over vegetation) give weak, wandering peaks.
MISREGISTRATION_MIN_PEAK = 0.2
MISREGISTRATION_MAX_SPREAD_PX = 1.0


def misregistration_reliable(peak: float, spread_px: float | None) -> bool:
    return peak >= MISREGISTRATION_MIN_PEAK and (
        spread_px is None or spread_px <= MISREGISTRATION_MAX_SPREAD_PX
    )


def _filled(
    band: np.ndarray, valid: np.ndarray | None, min_valid: float = 0.9
) -> np.ndarray | None:
    """Band as float with invalid pixels set to the valid mean; None if too few or flat."""
    a = band.astype(np.float64)
    if valid is not None:
        if valid.mean() < min_valid:
            return None
        a[~valid] = a[valid].mean()
    if float(a.std()) == 0.0:
        return None
    return a
