"""A measure provider: importing this module registers ``example.tile_name_ok``.

The agency's rule: an image file is named ``<flight_id>_<photo_number>.<extension>`` (JRC §5.3:
"Input files should be self-documenting (e.g. flight, photo number)"), so that a file found on a
disk names its own flight and photo. The provider only reads the delivery's images table (every
value comes with its table row as evidence); an image without a flight id or photo number is
``None`` (the rule's verdict is then ``missing``, never ``pass``).
"""

from __future__ import annotations

from pathlib import PurePosixPath

import pandas as pd

from orthospec.engine.registry import Measured, ProviderContext, RowEvidence, provider

NAME = "example.tile_name_ok"


def _blank(v: object) -> bool:
    return v is None or (isinstance(v, float) and v != v) or not str(v).strip()


@provider(scope="image", measures={NAME: "bool"})
def tile_name_ok(ctx: ProviderContext) -> list[Measured]:
    """The image file is named <flight_id>_<photo_number>.<ext> (self-documenting, JRC §5.3)."""
    t = ctx.delivery.table("images")
    if t is None:
        return [
            Measured(
                NAME,
                "image",
                "bool",
                pd.Series(dtype=object),
                pd.Series(dtype=object),
                notes=pd.Series({"*": "the manifest declares no images table"}, dtype=object),
            )
        ]
    df = t.df
    ids = t.ids.astype(str).tolist()
    values: dict[str, bool | None] = {}
    notes: dict[str, str] = {}
    for item, file, flight, photo in zip(
        ids,
        df["file"],
        df.get("flight_id", [None] * len(df)),
        df.get("photo_number", [None] * len(df)),
        strict=True,
    ):
        if _blank(flight) or _blank(photo):
            values[item] = None
            notes[item] = "no flight_id or photo_number in the images table"
            continue
        expected = f"{str(flight).strip()}_{str(photo).strip()}"
        values[item] = PurePosixPath(str(file)).stem == expected
        if not values[item]:
            notes[item] = f"file {file} is not named {expected}.<ext>"
    ev = RowEvidence(t.file, t.sha256, pd.Series(df["_row"].to_numpy(), index=ids))
    return [
        Measured(
            NAME,
            "image",
            "bool",
            pd.Series(values, dtype=object),
            ev,
            notes=pd.Series(notes, dtype=object) if notes else None,
        )
    ]
