"""The delivery as one evaluation judges it: the contractor's files, the checker's measurements.

JRC §12.4-§12.6: the external quality check measures *independent* check points on the delivered
orthoimages; the check points the contractor delivers are its internal QC (§12.5; §7.2 "The same
quality requirements apply for the check points used by the contractor for internal QC"). So in an
evaluation the ``checkpoints`` table - what the external-accuracy rules (§12.4-§12.8, Table 9,
NSSDA, USGS, ASPRS) and the §12.8 roll-up read - is the checker folder's
``tables/checkpoints.csv`` when the checker has measured, and the delivery's own table is then
``internal_checkpoints``, judged as the contractor's internal QC and compared with the external
result (engine/providers/internal_qc.py): the contractor's table cannot change an external verdict.

Without the checker's measurements (no checker, a single checker file, or a folder without the
table) the statistics are computed from the contractor's own points - §12.4 "QCR information may
permit use of contractor data where these show that the data are reliable (although it is not
recommended)" - and :attr:`DeliveryInForce.external` says so: the rule JRC-12.4-EXTERNAL-CHECKPOINTS
(measure ``checker.external_checkpoints``) keeps such a check from being accepted, while a failure
the contractor's own points show still rejects.

A checker's measurement is bound to the image it was made on (issue 29 item 4): a point whose
``image_sha256`` is not the SHA-256 of the image now delivered under its ``image_id`` (changed,
swapped, no longer delivered) or that records none is left out of the statistics and listed in
:attr:`DeliveryInForce.unbound` with the reason, never judged on other pixels.

:class:`DeliveryInForce` is made per evaluation (engine/context.py) and shares the opened
delivery's parsed tables and checksums; the opened ``Delivery`` itself is never changed, so a
second check of it without a checker judges as a fresh one (issue 26).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import pandas as pd

from .checker import CHECKPOINTS_TABLE, Checker
from .checker_tables import EVIDENCE_PREFIX, read_checker_points
from .reader import Delivery, Table

#: the delivery's own check point table, as an evaluation names it
INTERNAL = "internal_checkpoints"


@dataclass(frozen=True)
class Unbound:
    """A checker's point left out: its measurement is not bound to the image delivered now."""

    point_id: str
    block: str
    row: int
    image_id: str | None
    reason: str


@dataclass
class DeliveryInForce(Delivery):
    """The delivery, with the external QC's check points as its ``checkpoints`` table (see module doc)."""

    checker: Checker | None = field(default=None, repr=False)
    #: the checker's table as read, before unbound points are left out (None: the checker has none)
    _external: Table | None = field(default=None, repr=False)
    _resolved: bool = field(default=False, repr=False)
    #: the checker's points left out (their image changed, was swapped or is not delivered)
    unbound: list[Unbound] = field(default_factory=list, repr=False)
    #: ids of the checker's points that record no image SHA-256 (kept; not bound to image content)
    unhashed: list[str] = field(default_factory=list, repr=False)
    _checker_sha: dict[str, str] = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, d: Delivery, checker: Checker | None) -> DeliveryInForce:
        """The evaluation's view of ``d`` (its tables and checksums shared, nothing written onto ``d``).

        Reads the checker folder's table now, so a bad table is exit 2 before any rule runs."""
        base = d.delivery if isinstance(d, DeliveryInForce) else d
        view = cls(**{f.name: getattr(base, f.name) for f in fields(Delivery)}, checker=checker)
        if checker is not None:
            got = read_checker_points(checker, base)
            if got is not None:
                view._external = got.table
                view._checker_sha[got.table.file] = got.table.sha256
        return view

    @property
    def external(self) -> bool:
        """The ``checkpoints`` table in force is the checker's own measurements (not the contractor's)."""
        return self._external is not None

    @property
    def delivery(self) -> Delivery:
        """The opened delivery this view is of (a plain ``Delivery``, as the caller gave it)."""
        return Delivery(**{f.name: getattr(self, f.name) for f in fields(Delivery)})

    # --- the tables in force --------------------------------------------------------------
    def has_table(self, name: str) -> bool:
        if name == "checkpoints" and self.external:
            return True
        if name == INTERNAL:
            return self.external and super().has_table("checkpoints")
        return super().has_table(name)

    def table(self, name: str) -> Table | None:
        if name == "checkpoints" and self.external:
            return self._bound()
        if name == INTERNAL:
            return super().table("checkpoints") if self.external else None
        return super().table(name)

    def table_absent_reason(self, name: str) -> str:
        if name == INTERNAL:
            if not self.external:
                return (
                    "the check point statistics are the contractor's own points (no checker's measurements): "
                    "nothing independent to compare its internal QC with"
                )
            return super().table_absent_reason("checkpoints")
        return super().table_absent_reason(name)

    def external_absent_reason(self) -> str:
        """Why the check points in force are the contractor's (for JRC-12.4-EXTERNAL-CHECKPOINTS), '' if not."""
        if self.external:
            return ""
        need = (
            f"the checker measured no check points of its own (CHECKER_DIR/{CHECKPOINTS_TABLE}: orthospec "
            "measure checkpoints; JRC §12.4-§12.6)"
        )
        then = "so the statistics are the contractor's own points (internal QC, JRC §12.5)"
        if self.checker is None:
            return f"{need}: no checker folder was given (--checker), {then}"
        if self.checker.folder is None:
            return f"{need}: the single checker file {self.checker.display} holds no tables, {then}"
        return (
            f"{need}: the checker folder {self.checker.folder} holds no {CHECKPOINTS_TABLE}, {then}"
        )

    def sha256(self, rel: str) -> str:
        if rel.startswith(EVIDENCE_PREFIX):
            return self._checker_sha[rel]
        return super().sha256(rel)

    # --- binding of the checker's points to the images measured --------------------------
    def _bound(self) -> Table | None:
        """The checker's table without its unbound points (computed once per evaluation)."""
        t = self._external
        if t is None or self._resolved:
            return t
        self._resolved = True
        keep, self.unbound = self._binding(t)
        if not keep.all():
            t = Table(
                t.name, t.spec, t.file, t.sha256, t.df.loc[keep].reset_index(drop=True), t.units
            )
            self._external = t
        return t

    def _binding(self, t: Table) -> tuple[np.ndarray, list[Unbound]]:
        """Which of the checker's rows are bound to the image delivered now; the others, with why.

        A row records the image it was measured on (``image_id``) and that image's SHA-256 when measured
        (``image_sha256``, written by the tool). A row with a SHA-256 is kept only when its image is still
        delivered with that content. A row with none cannot be checked: it is kept and counted in
        :attr:`unhashed` (JRC-12.6-POINTS-HASHED names it)."""
        df = t.df
        n = len(df)
        keep = np.ones(n, dtype=bool)
        ids = (
            df["image_id"].to_numpy(dtype=object)
            if "image_id" in df
            else np.full(n, None, dtype=object)
        )
        shas = (
            df["image_sha256"].to_numpy(dtype=object)
            if "image_sha256" in df
            else np.full(n, None, dtype=object)
        )
        hashed = np.array([v is not None for v in shas], dtype=bool)
        self.unhashed = [str(v) for v in df["point_id"].to_numpy(dtype=object)[~hashed]]
        if not hashed.any():
            return keep, []
        files = self._image_files()
        now = {
            image: (self._hash(files[image]) if image in files else None)
            for image in sorted({str(ids[i]) for i in np.flatnonzero(hashed) if ids[i] is not None})
        }
        out: list[Unbound] = []
        rows = df["_row"].to_numpy()
        for i in np.flatnonzero(hashed).tolist():
            image, sha = ids[i], str(shas[i]).lower()
            current = None if image is None else now.get(str(image))
            if image is None:
                why = "the measurement records an image_sha256 but no image_id: it names no delivered image"
            elif str(image) not in files:
                why = f"image {image} is no longer delivered (the images table does not list it with a file)"
            elif current is None:
                why = f"image {image}'s file {files[str(image)]} is not in the delivery"
            elif sha != current:
                why = (
                    f"measured on image {image} with SHA-256 {sha[:12]}…; the delivered {files[str(image)]} is "
                    f"{current[:12]}… (changed or swapped since): measure it again"
                )
            else:
                continue
            keep[i] = False
            out.append(
                Unbound(
                    str(df["point_id"].iat[i]),
                    str(df["block"].iat[i]),
                    int(rows[i]),
                    None if image is None else str(image),
                    why,
                )
            )
        return keep, out

    def _image_files(self) -> dict[str, str]:
        imgs = super().table("images")
        if imgs is None or "file" not in imgs.df:
            return {}
        cells = imgs.df["file"]
        have = cells.notna().to_numpy()
        return dict(zip(imgs.ids[have].tolist(), cells[have].astype(str).tolist(), strict=True))

    def _hash(self, rel: str) -> str | None:
        try:
            p = self.path(rel, what="images file")
        except Exception:  # a path the delivery refuses is reported where the images table is read
            return None
        return self.sha256(rel) if p.is_file() else None

    def unbound_frame(self) -> pd.DataFrame:
        """The unbound points as a table (point_id, block, row, image_id, reason), in file order."""
        self.table("checkpoints")
        return pd.DataFrame(
            [vars(u) for u in self.unbound],
            columns=["point_id", "block", "row", "image_id", "reason"],
        )

    def checker_evidence(self) -> dict[str, Any]:
        """The checker's files this view reads, by evidence name -> SHA-256."""
        return dict(self._checker_sha)
