"""The library entry points the CLI (and other programs) call."""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .delivery.reader import Delivery, open_delivery
from .engine.evaluator import Evaluation, Evaluator
from .engine.params import parse_cli_params, resolve_parameters
from .errors import OrthospecError
from .qcr import build_document
from .spec.loader import ResolvedProfile, load_profile


@dataclass
class CheckResult:
    document: dict[str, Any]
    evaluation: Evaluation

    @property
    def accepted(self) -> bool:
        return self.document["verdict"] == "accepted"


def parse_date(text: str | None) -> str:
    if text is None:
        return dt.date.today().isoformat()
    try:
        return dt.date.fromisoformat(text).isoformat()
    except ValueError:
        raise OrthospecError(f"--date {text!r}: expected YYYY-MM-DD") from None


def check(delivery: str | Path | Delivery, profile: str | Path | ResolvedProfile, *,
          params: Mapping[str, str] | list[str] | tuple[str, ...] = (), date: str | None = None,
          fail_on: str = "fail", operator: str | None = None,
          options: Mapping[str, Any] | None = None) -> CheckResult:
    """Check a delivery against a profile; bad input raises OrthospecError, failures are QCRs."""
    if fail_on not in ("fail", "warn"):
        raise OrthospecError(f"fail_on must be 'fail' or 'warn', got {fail_on!r}")
    prof = profile if isinstance(profile, ResolvedProfile) else load_profile(profile)
    d = delivery if isinstance(delivery, Delivery) else open_delivery(delivery)
    d.load_all_tables()
    cli = dict(params) if isinstance(params, Mapping) else parse_cli_params(list(params))
    values = resolve_parameters(prof, dict(d.manifest.tender.parameters) if d.manifest.tender else {}, cli)
    ev = Evaluator(prof, d, values, fail_on=fail_on, options=options).run()
    shown = str(delivery) if not isinstance(delivery, Delivery) else d.root.name
    doc = build_document(ev, date=parse_date(date), operator=operator, delivery_path=_display(shown))
    return CheckResult(doc, ev)


def _display(path: str) -> str:
    """A relative, stable display path (absolute paths would break byte-identical output)."""
    p = Path(path)
    if p.is_absolute():
        try:
            return p.resolve().relative_to(Path.cwd().resolve()).as_posix()
        except ValueError:
            return p.name
    return p.as_posix().rstrip("/")
