"""Image chips of a check point, delivered beside reference, with the measured shift drawn (SVG).

Issue 29 item 6: for a flagged or hand-measured point of the checker's table, the report shows the
delivered orthoimage around the measured position and the reference chip around the 'true'
position; on the delivered chip the reference position (green circle), the measured one (red
cross) and the shift between them (arrow, to scale: the chips are in map units). Deterministic SVG
text as figures/accuracy.py (same settings); the chips come from qcr.json
(``details.checker_chips``, inspection/chips.py), so nothing is read or fetched here.
"""

from __future__ import annotations

from typing import Any

import matplotlib

matplotlib.use("Agg", force=False)

import matplotlib.pyplot as plt

from ..inspection.chips import Chip
from .accuracy import _RC, _svg

__all__ = ["chip_svg"]


def chip_svg(point: dict[str, Any], *, unit: str = "m") -> str:
    """The two chips of ``point`` (an entry of ``details.checker_chips``), as SVG text; a chip that could
    not be cut is a panel stating why."""
    delivered = Chip.from_dict(point["delivered"]) if point.get("delivered") else None
    reference = Chip.from_dict(point["reference"]) if point.get("reference") else None
    x, y, xr, yr = (float(point[k]) for k in ("x", "y", "x_ref", "y_ref"))
    with plt.rc_context(_RC):
        fig, axes = plt.subplots(1, 2, figsize=(6.4, 3.3))
        for ax, chip, title, note in (
            (
                axes[0],
                delivered,
                f"delivered ({point.get('image_id') or '?'})",
                point.get("delivered_note"),
            ),
            (axes[1], reference, "reference", point.get("reference_note")),
        ):
            ax.set_title(title, fontsize=8)
            if chip is None:
                ax.text(
                    0.5,
                    0.5,
                    note or "no chip",
                    ha="center",
                    va="center",
                    wrap=True,
                    fontsize=7,
                    transform=ax.transAxes,
                )
                ax.set_xticks([])
                ax.set_yticks([])
                continue
            left, bottom, right, top = chip.extent
            im = ax.imshow(
                chip.data,
                cmap="gray",
                vmin=0,
                vmax=255,
                extent=(left, right, bottom, top),
                interpolation="nearest",
            )
            im.set_gid("chip-" + ("delivered" if chip is delivered else "reference"))
            ref = ax.scatter(
                [xr],
                [yr],
                s=50,
                facecolors="none",
                edgecolors="tab:green",
                linewidths=1.4,
                zorder=3,
                label="reference ('true')",
            )
            ref.set_gid("reference-position")
            if chip is delivered:
                mea = ax.scatter(
                    [x],
                    [y],
                    marker="x",
                    s=50,
                    color="tab:red",
                    linewidths=1.4,
                    zorder=4,
                    label="measured",
                )
                mea.set_gid("measured-position")
                if (x, y) != (xr, yr):
                    arrow = ax.annotate(
                        "",
                        xy=(x, y),
                        xytext=(xr, yr),
                        arrowprops={"arrowstyle": "->", "color": "tab:red", "lw": 1.2},
                    )
                    arrow.arrow_patch.set_gid(
                        "measured-shift"
                    )  # the Annotation itself writes no group
            ax.set_xlim(left, right)
            ax.set_ylim(bottom, top)
            ax.tick_params(labelsize=6)
            ax.ticklabel_format(useOffset=False, style="plain")
        dx, dy = x - xr, y - yr
        fig.suptitle(
            f"{point['point_id']}: shift dx {dx:+.3f} {unit}, dy {dy:+.3f} {unit}"
            + (f" ({point['decision']})" if point.get("decision") else ""),
            fontsize=9,
        )
        handles, labels = axes[0].get_legend_handles_labels()
        if handles:
            fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=7, frameon=False)
        fig.tight_layout(rect=(0, 0.06, 1, 1))
        return _svg(fig)
