"""How the orthoimages were produced, computed from the blocks rather than trusting a declared flag.

* ``derived.orthorectification`` (delivery): ``space_resection`` when any block of the manifest was
  produced by space resection (or the manifest says so), else the declared or block method. JRC
  §12.8 footnote 6 ("For projects where space resection has been used in the production of
  individual orthophotos should any block fail, the dataset will be subject to redelivery") keys on
  it; the manifest's ``product.orthorectification`` alone is a flag the contractor may omit.
"""

from __future__ import annotations

import pandas as pd

from ..registry import Measured, ProviderContext, provider
from .cells import norm as _norm

DELIVERY = {"derived.orthorectification": "text"}


@provider(scope="delivery", measures=DELIVERY)
def orthorectification(ctx: ProviderContext) -> list[Measured]:
    """How the orthoimages were produced, from the blocks' methods and the manifest."""
    d = ctx.delivery
    methods = {b.id: _norm(b.method) for b in d.manifest.blocks}
    declared = _norm(getattr(d.manifest.product, "orthorectification", None))
    sr = sorted(b for b, m in methods.items() if m == "space_resection")
    ev = (d.manifest_evidence("blocks"), d.manifest_evidence("product.orthorectification"))
    note = None
    if sr:
        value: str | None = "space_resection"
        note = f"block(s) {', '.join(sr)} produced by space resection (blocks[].method)"
    elif declared:
        value = declared
        note = "declared in delivery.yaml product.orthorectification"
    else:
        known = sorted({m for m in methods.values() if m})
        value = known[0] if len(known) == 1 else None
        note = (
            f"blocks[].method: {known[0]}"
            if len(known) == 1
            else "delivery.yaml gives no product.orthorectification and the blocks' methods "
            + ("disagree (" + ", ".join(known) + ")" if known else "are not given")
        )
    return [
        Measured(
            "derived.orthorectification",
            "delivery",
            "text",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        )
    ]
