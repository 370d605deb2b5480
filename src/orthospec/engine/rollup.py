"""Roll-up: from item verdicts to rejected items, blocks and the delivery's verdict.

The second phase of an evaluation (JRC §12.3, §12.7, §12.8). Which items a finding rejects
follows the rule's consequence; the shares of rejected images and blocks come from the one
implementation in :mod:`orthospec.measures.acceptance` and are offered to the profile's
``rollup.*`` rules as measures. Every mandatory rule can change the verdict: only a *mandatory*
roll-up rule replaces the default "any rejected image/block returns the delivery"; a failing
mandatory rule with consequence ``warn`` returns the delivery; a finding for the whole scope
(item ``*``) returns it. A block a rule rejected stays in the §12.8 denominator even without
check points; images a rule rejected count as tested.

Findings that are the checker's to fix (consequence ``incomplete``; a manual check the checker has
not signed) reject nothing: they keep the check open (engine/incomplete.py says what to add), the
verdict is ``incomplete`` unless a real failure rejects the delivery.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from .. import verdicts as V
from ..delivery.convention import table_of_scope
from ..errors import OrthospecError
from ..measures.acceptance import (
    DeliveryVerdict,
    ProjectVerdict,
    image_delivery_verdict,
    project_verdict,
)
from ..profile.models import Rule
from ..profile.operators import is_missing
from ..provenance import Evidence
from .context import ERROR, FAIL, MISSING, VERDICTS, WARN, Context, RuleResult
from .incomplete import Entry, checker_mask, lines, todo
from .manual import gone_reason, vanished_in
from .registry import ROLLUP, Measured

BLOCK_ROLLUPS = ("rollup.block_rejected_share", "rollup.blocks_rejected")
IMAGE_ROLLUPS = (
    "rollup.image_rejected_share",
    "rollup.image_failed_share",
    "rollup.images_rejected",
)


def _every_row(t: Any) -> tuple[Evidence, ...]:
    """Evidence naming every data row of a table. Rows 1..n without a gap (no blank line) are a
    ``range`` (the same rows in constant memory: a million check points would hold 40 MB of ints),
    else a tuple built by numpy."""
    rows = t.df["_row"].to_numpy(dtype=np.int64)
    n = len(rows)
    if n and rows[0] == 1 and rows[-1] == n and bool((np.diff(rows) == 1).all()):
        return (Evidence(t.file, t.sha256, range(1, n + 1)),)  # type: ignore[arg-type]
    return (Evidence(t.file, t.sha256, tuple(rows.tolist())),)


class Rollup:
    """Rejected items per scope, the roll-up measures, and the delivery's verdict with its reasons."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        #: findings that could not be tied to items: they return the delivery
        self.scope_wide: list[str] = []
        self.image_verdict: DeliveryVerdict | None = None
        self.image_failed_verdict: DeliveryVerdict | None = None
        self.block_verdict: ProjectVerdict | None = None

    def open_findings(self, r: RuleResult) -> np.ndarray:
        """Per item: this verdict keeps the delivery from acceptance (fail/missing/error; warn with
        --fail-on warn), whether it rejects or leaves the check incomplete."""
        warn = self.ctx.fail_on == V.WARN
        if r.rule.level == "recommended" and not warn:
            return np.zeros(len(r.verdict), dtype=bool)
        return np.isin(r.verdict, (FAIL, MISSING, ERROR) + ((WARN,) if warn else ()))

    def blocking(self, r: RuleResult) -> np.ndarray:
        """Per item: this verdict rejects (its item, block or the delivery, by the rule's consequence);
        the checker's own open findings (:func:`~.incomplete.checker_mask`) do not."""
        mask = self.open_findings(r)
        return mask & ~checker_mask(r, mask) if mask.any() else mask

    def incomplete(self, results: list[RuleResult]) -> list[str]:
        """What the checker must still add or do, one line per open item (engine/incomplete.py)."""
        totals = self._totals()
        entries: list[Entry] = []
        for r in results:
            mask = self.open_findings(r)
            if mask.any() and (mine := checker_mask(r, mask)).any():
                entries += todo(r, mine, totals)
        return lines(entries)

    def _totals(self) -> dict[str, int]:
        """How many images and blocks a sample share is a share of."""
        imgs = self.ctx.d.table("images")
        return {
            "rollup.images_sampled_share": len(imgs.df) if imgs is not None else 0,
            "rollup.blocks_checked_share": len(self.ctx.d.block_ids),
        }

    def blocks_of(self, scope: str) -> dict[str, set[str]] | None:
        """item -> blocks it belongs to / serves, from the scope's table `block` column
        (';'-separated for an item serving several blocks, e.g. a DEM; a DEM without one is placed
        by its file's footprint, derived.dem_blocks); None when unknown."""
        if scope == "dem":
            try:
                m = self.ctx.cache.get("derived.dem_blocks")
            except OrthospecError:
                return None
            return {
                str(k): {x for x in str(v).split(";") if x}
                for k, v in m.values.items()
                if not is_missing(v)
            }
        table = table_of_scope(scope)
        t = self.ctx.d.table(table) if table else None
        if t is None or "block" not in t.df:
            return None
        out: dict[str, set[str]] = {}
        for item, b in zip(t.ids.astype(str).tolist(), t.df["block"].tolist(), strict=True):
            if not is_missing(b):
                out[item] = {x.strip() for x in str(b).split(";") if x.strip()}
        return out

    # --- phase 2a: which items the findings reject
    def rejected_items(self, results: list[RuleResult]) -> tuple[dict[str, list[str]], list[str]]:
        rejected: dict[str, set[str]] = {}
        reasons: list[str] = []
        for r in results:
            mask = self.blocking(r)
            if not mask.any():
                continue
            items = self._tied_items(r, mask)
            c = r.rule.consequence
            if not items:
                continue
            if c == "reject_item":
                rejected.setdefault(r.rule.scope, set()).update(items)
            elif c == "reject_block":
                blocks = self._blocks_rejected(r.rule, items)
                if blocks:
                    rejected.setdefault("block", set()).update(blocks)
                    reasons.append(
                        f"{r.rule.id} ({r.rule.clause.text()}) rejects block(s) "
                        + ", ".join(sorted(blocks))
                    )
        return {k: sorted(v) for k, v in sorted(rejected.items())}, reasons

    def _tied_items(self, r: RuleResult, mask: np.ndarray) -> list[str]:
        """The blocking items; a finding for the whole scope (`*`) is noted to return the delivery."""
        items = [str(i) for i in r.items[mask]]
        if "*" in items and r.rule.consequence in ("reject_item", "reject_block"):
            v = VERDICTS[int(r.verdict[mask][0])]
            note = next((str(x) for x in r.notes[mask] if x), "")
            self.scope_wide.append(
                f"{r.rule.id} ({r.rule.clause.text()}): {v} for the whole {r.rule.scope} "
                f"scope, not for named items ({note[:160]}): the delivery is returned"
            )
            items = [i for i in items if i != "*"]
        return items

    def _blocks_rejected(self, rule: Rule, items: list[str]) -> set[str]:
        """The blocks a reject_block finding on ``items`` rejects; items with unknown blocks are noted."""
        if rule.scope == "block":
            return set(items)
        bmap = self.blocks_of(rule.scope)
        blocks = set().union(*(bmap.get(i, set()) for i in items)) if bmap else set()
        unmapped = [i for i in items if not bmap or not bmap.get(i)]
        if unmapped:
            self.scope_wide.append(
                f"{rule.id} ({rule.clause.text()}) rejects {rule.scope} item(s) {', '.join(unmapped[:5])} but "
                "the blocks they serve are unknown (no `block` column value for them): the finding stands at "
                "delivery level and the delivery is returned"
            )
        return blocks

    # --- phase 2b: the roll-up measures (JRC §12.3 / §12.8, measures/acceptance)
    def _param_number(self, name: str, default: float) -> float:
        p = self.ctx.params.get(name)
        v = getattr(p, "value", None)
        return (
            float(v)
            if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            else default
        )

    def _sampled_images(
        self, all_imgs: list[str], imgs: Any, rejected: dict[str, list[str]]
    ) -> list[str]:
        given = self.ctx.options.sample
        if given and given[0] == "image":
            return [i for i in all_imgs if i in given[1]]
        if "sample" in imgs.df and imgs.df["sample"].map(lambda v: v is True).any():
            # the `sample` column travels with the delivery: an image the rules checked and
            # rejected counts as tested whether or not it is marked, so marking only good
            # images cannot shrink the failure share (issue 17, fail-open by the contractor)
            marked = set(imgs.ids[imgs.df["sample"].map(lambda v: v is True)].astype(str).tolist())
            failed = set(rejected.get("image", []))
            return [i for i in all_imgs if i in marked or i in failed]
        return all_imgs

    def _image_shares(
        self, rejected: dict[str, list[str]], max_share: float, results: list[RuleResult]
    ) -> tuple[float | None, float | None, set[str], float | None]:
        """(rejected-image share %, sampled share %, rejected sampled images, failed-image share %)
        per JRC §12.3; an image fails when a rule rejects it or a rule of the criteria sections
        (:meth:`_failing_images`) fails or warns for it."""
        imgs = self.ctx.d.table("images")
        if imgs is None:
            return None, None, set(), None
        all_imgs = imgs.ids.astype(str).tolist()
        sampled = self._sampled_images(all_imgs, imgs, rejected)
        rej = set(rejected.get("image", [])) & set(sampled)
        samp = 100.0 * len(sampled) / len(all_imgs) if all_imgs else None
        share = failed_share = None
        if sampled:
            action = getattr(self.ctx.params.get("image_fail_share_action"), "value", None)
            self.image_verdict = image_delivery_verdict(
                len(all_imgs),
                [i in rej for i in sampled],
                sampled_ids=sampled,
                max_failed_fraction=max_share,
                returns=action != "keep",
            )
            share = 100.0 * self.image_verdict.failed_fraction
            failing = rej | self._failing_images(results)
            self.image_failed_verdict = image_delivery_verdict(
                len(all_imgs),
                [i in failing for i in sampled],
                sampled_ids=sampled,
                max_failed_fraction=max_share,
                returns=action != "keep",
            )
            failed_share = 100.0 * self.image_failed_verdict.failed_fraction
        return share, samp, rej, failed_share

    def _criteria_sections(self) -> tuple[str, ...]:
        """The clause sections whose image rules §12.3 checks (parameter image_criteria_sections)."""
        v = getattr(self.ctx.params.get("image_criteria_sections"), "value", None)
        return (
            tuple(x.strip() for x in str(v).replace(";", ",").split(",") if x.strip()) if v else ()
        )

    def _failing_images(self, results: list[RuleResult]) -> set[str]:
        """Images for which an image rule of the criteria sections fails or warns (JRC §12.3: "fail
        on one or more of these specifications"; Chapter 6's criteria are mostly "should", so their
        rules warn: a warning is a failed criterion here). Waived findings do not count."""
        sections = self._criteria_sections()
        out: set[str] = set()
        if not sections:
            return out
        for r in results:
            sec = str(r.rule.clause.section or "")
            if r.rule.scope != "image" or not any(
                sec == x or sec.startswith(x + ".") for x in sections
            ):
                continue
            bad = np.isin(r.verdict, (FAIL, WARN))
            if bad.any():
                out.update(str(i) for i in r.items[bad])
        return out

    def _block_shares(
        self, rejected: dict[str, list[str]], max_share: float
    ) -> tuple[float | None, float | None, set[str]]:
        """(rejected-block share %, blocks-with-points share %, rejected blocks) per JRC §12.8."""
        d = self.ctx.d
        blocks = d.block_ids
        cps = d.table("checkpoints")
        # distinct values first (vectorised), then text: a million points hold a handful of blocks
        with_points = (
            set(map(str, pd.unique(cps.df["block"].to_numpy(dtype=object)).tolist())) & set(blocks)
            if cps is not None
            else set()
        )
        brej = set(rejected.get("block", [])) & set(blocks)
        # a declared block without check points is missing evidence, never dropped from the share:
        # the blocks subjected to external QC are those with points plus those a rule rejected
        checked = sorted(with_points | brej)
        given = self.ctx.options.sample
        if given and given[0] == "block":
            checked = [b for b in checked if b in given[1]]
        bshare = None
        if blocks and checked:
            self.block_verdict = project_verdict(
                len(blocks),
                [b not in brej for b in checked],
                checked_ids=checked,
                max_failed_fraction=max_share,
                space_resection=self._space_resection(),
            )
            bshare = 100.0 * self.block_verdict.failed_fraction
        elif blocks:
            bshare = 0.0 if not brej else 100.0
        return bshare, (100.0 * len(with_points) / len(blocks) if blocks else None), brej

    def measures(
        self, rejected: dict[str, list[str]], results: Sequence[RuleResult] = ()
    ) -> dict[str, Measured]:
        """The ``rollup.*`` measures from the item verdicts of the first phase."""
        d = self.ctx.d
        max_share = self._param_number("fail_share_max", 5.0) / 100.0
        imgs, cps = d.table("images"), d.table("checkpoints")
        ev_img = _every_row(imgs) if imgs is not None else (d.manifest_evidence("tables"),)
        ev_blk = _every_row(cps) if cps is not None else (d.manifest_evidence("blocks"),)
        share, samp, rej, failed = self._image_shares(rejected, max_share, list(results))
        bshare, bchecked, brej = self._block_shares(rejected, max_share)
        vals = {
            "rollup.image_rejected_share": (share, ev_img),
            "rollup.images_sampled_share": (samp, ev_img),
            "rollup.image_failed_share": (failed, ev_img),
            "rollup.images_rejected": (float(len(rej)) if imgs is not None else None, ev_img),
            "rollup.block_rejected_share": (bshare, ev_blk),
            "rollup.blocks_checked_share": (bchecked, ev_blk),
            "rollup.blocks_rejected": (float(len(brej)), ev_blk),
        }
        out: dict[str, Measured] = {}
        for name, (v, ev) in vals.items():
            scope, unit = ROLLUP[name]
            item = d.id if scope == "delivery" else d.project_id
            out[name] = Measured(
                name,
                scope,
                unit,
                pd.Series({item: v}, dtype=object),
                pd.Series({item: ev}, dtype=object),
            )
        return out

    def _space_resection(self) -> bool:
        """JRC §12.8 footnote 6 applies: the orthophotos were produced by space resection."""
        try:
            m = self.ctx.cache.get("derived.orthorectification")
        except OrthospecError:
            return False
        return bool(len(m.values)) and m.values.iloc[0] == "space_resection"

    # --- phase 2c: the delivery's verdict
    def _rule_reasons(self, r: RuleResult, mask: np.ndarray) -> str | None:
        items = ", ".join(str(i) for i in r.items[mask][:5])
        v = VERDICTS[int(r.verdict[mask][0])]
        if r.rule.consequence == "warn" and r.rule.level == "mandatory":
            # every mandatory rule can change the verdict: `warn` cannot make a failing
            # mandatory requirement acceptable (issue 12); the finding returns the delivery
            return (
                f"{r.rule.id} ({r.rule.clause.text()}): mandatory rule {v} for {items}; its consequence "
                "'warn' cannot accept a failing mandatory requirement"
            )
        if r.rule.consequence == "return_delivery" or (
            r.rule.consequence == "reject_block" and r.rule.scope in ("delivery", "project")
        ):
            return f"{r.rule.id} ({r.rule.clause.text()}): {v} for {items}"
        return None

    def _default_rollups(self, rejected: dict[str, list[str]], second: list[Rule]) -> list[str]:
        """Rejected images/blocks return the delivery unless a MANDATORY roll-up rule decides (a
        recommended one cannot change the verdict, so it must not switch the default off)."""
        has = {m for r in second if r.level == "mandatory" for m in (r.measure,)}
        reasons = []
        if rejected.get("block") and not has & set(BLOCK_ROLLUPS):
            bv = self.block_verdict
            reasons.append(
                "block(s) " + ", ".join(rejected["block"]) + " rejected and the profile has no "
                "mandatory project-level roll-up rule: any rejected block returns the delivery"
                + (f" (JRC §12.8: {bv.reason})" if bv is not None else "")
            )
        if rejected.get("image") and not has & set(IMAGE_ROLLUPS):
            iv = self.image_verdict
            reasons.append(
                "image(s) rejected and the profile has no mandatory delivery-level roll-up rule: "
                "any rejected image returns the delivery"
                + (f" (JRC §12.3: {iv.reason})" if iv is not None else "")
            )
        for scope, items in rejected.items():
            if scope in ("image", "block") or not items:
                continue  # these two have the JRC §12.3 / §12.8 roll-up rules above
            shown = ", ".join(items[:5]) + (f" (+{len(items) - 5} more)" if len(items) > 5 else "")
            reasons.append(
                f"{scope} item(s) {shown} rejected and no roll-up rule covers the {scope} scope: "
                "a rejected item returns the delivery"
            )
        return reasons

    def _vanished(self, results: list[RuleResult]) -> list[str]:
        """A checker verdict on an item the delivery no longer lists returns the delivery (red team
        R15): what the checker inspected, and perhaps rejected, cannot leave the delivery unseen."""
        by_item: dict[str, list[str]] = {}
        for r in results:
            for item in vanished_in(self.ctx, r):
                hit = np.flatnonzero(r.items.astype(str) == item)
                v = VERDICTS[int(r.verdict[hit[0]])] if len(hit) else "not evaluated"
                by_item.setdefault(item, []).append(f"{r.rule.id} {v}")
        return [
            f"{gone_reason(item)} ({', '.join(rules)}): the delivery is returned"
            for item, rules in sorted(by_item.items())
        ]

    def overall(
        self, results: list[RuleResult], rejected: dict[str, list[str]], second: list[Rule]
    ) -> tuple[str, list[str], list[str]]:
        """The delivery's verdict, why it is rejected, and what the checker must still do (no
        reason and nothing to do = accepted; nothing rejects but something to do = incomplete)."""
        reasons: list[str] = list(self.scope_wide) + self._vanished(results)
        for r in results:
            mask = self.blocking(r)
            if mask.any() and (why := self._rule_reasons(r, mask)) is not None:
                reasons.append(why)
        if self.ctx.fail_on == V.WARN:
            warned = [r.rule.id for r in results if (self.blocking(r) & (r.verdict == WARN)).any()]
            if warned:
                reasons.append(
                    f"--fail-on warn: recommended-level rule(s) not met: {', '.join(warned[:10])}"
                    + (f" (+{len(warned) - 10} more)" if len(warned) > 10 else "")
                )
        reasons += self._default_rollups(rejected, second)
        todo_ = self.incomplete(results)
        return V.overall(bool(reasons), bool(todo_)), reasons, todo_
