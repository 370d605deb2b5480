"""The rich terminal summary of a check: verdict, findings (measured against required), counts.

Findings come from :mod:`.findings` (the same list as page 1 of the PDF). Every text that comes
from a delivery or profile passes :func:`~.findings.clean_text` (no ANSI/OSC escapes reach the
terminal) and rich markup escaping. Off a TTY nothing is cut: long lines wrap, never end in "…".
"""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from .. import verdicts as V
from ..qcr import all_records
from .contract import contract_lines
from .findings import checker_text, clean_text, findings, reason_line, unsigned_manual_note

MAX_ITEMS = 8
_STYLE = {V.PASS: "green", V.FAIL: "bold red", V.WARN: "yellow", V.MISSING: "magenta",
          V.ERROR: "bold red", V.WAIVED: "cyan", V.NOT_APPLICABLE: "dim"}
_OVERALL_STYLE = {V.ACCEPTED: "green", V.INCOMPLETE: "magenta"}


def _t(text: Any) -> str:
    return escape(clean_text(text))


def summary_line(doc: dict[str, Any]) -> str:
    s = doc["summary"]
    return (f"{s['rules']} rules, {s['records']} records: {s['pass']} passed, {s['warn']} warned, "
            f"{s['fail']} failed, {s['waived']} waived, {s['missing']} missing, "
            f"{s['not_applicable']} not applicable, {s['error']} errors")


def render(
    doc: dict[str, Any], console: Console, *, max_items: int = MAX_ITEMS, verbose: bool = False
) -> None:
    p, d = doc["profile"], doc["delivery"]
    verdict = doc["verdict"].upper()
    colour = _OVERALL_STYLE.get(doc["verdict"], "red")
    console.print(
        f"[bold]orthospec[/] {_t(d['path'])} against {_t(p['id'])} {_t(p['version'])} "
        f"(sha256 {p['sha256'][:12]}…), {doc['date']}",
        overflow="fold",
    )
    checker = checker_text(doc)
    qa = d.get("operator") or {}
    console.print(
        f"checker: {_t(checker) if checker else '(not named: --operator NAME or --checker FILE)'}; "
        "contractor QA "
        f"operator: {_t(qa.get('name', '')) or '-'}"
        + (f" ({_t(qa['role'])})" if qa.get("role") else ""),
        overflow="fold",
    )
    contract = contract_lines(doc)  # page 1 says the same (reports/contract.py)
    for line in contract["parameters"]:
        console.print(f"[yellow]values in force:[/] {_t(line)}", overflow="fold")
    for line in contract["weakened"]:
        console.print(
            f"[yellow]mandatory rule weakened by the tender:[/] {_t(line)}", overflow="fold"
        )
    sample = doc.get("sample")
    if isinstance(sample, dict) and sample.get("statement"):
        console.print(f"sample: {_t(sample['statement'])}", overflow="fold")
    records = list(
        all_records(doc, compact=False)
    )  # problems only: bounded by them, not by the delivery
    found = findings(records)
    if found:
        t = Table(show_header=True, header_style="bold", box=None, pad_edge=False)
        t.add_column("verdict", no_wrap=True, min_width=7)
        t.add_column(
            "finding (item: rule title: measured against required, clause)",
            ratio=1,
            overflow="fold",
        )
        t.add_column("rule", no_wrap=True, overflow="fold")
        for f in found:
            items = f.items
            shown = ", ".join(items[:max_items]) + (
                f" … (+{len(items) - max_items} more)" if len(items) > max_items else ""
            )
            if len(f.rules) > 1:
                text = f"{shown}: {f.what} ({len(f.rules)} checks affected: {', '.join(f.rules)})"
            else:
                text = f"{shown}: {f.title}: {f.what} ({f.clause})"
            t.add_row(f"[{_STYLE.get(f.verdict, '')}]{f.verdict}[/]", _t(text), _t(f.rule))
        console.print(t)
        console.print(_t(reason_line(found)), overflow="fold")
    if verbose:
        for r in doc["rules"]:
            if r["verdict"] in (V.PASS, V.WAIVED):
                console.print(
                    f"  [{_STYLE.get(r['verdict'], '')}]{r['verdict']}[/] {_t(r['rule'])} "
                    f"{_t(r['title'])}",
                    overflow="fold",
                )
    for reason in doc["rollup"]["reasons"]:
        console.print(f"  [red]•[/] {_t(reason)}", overflow="fold")
    todo = doc["rollup"].get("incomplete") or []
    if todo:
        console.print(f"[magenta]the check is incomplete: the checker must still ({len(todo)}):[/]")
        for line in todo:
            console.print(f"  [magenta]•[/] {_t(line)}", overflow="fold")
    for st in doc.get("nssda") or ():
        warn = (
            ""
            if st.get("valid", True)
            else " (RMSE ratio below 0.6: the approximation does not hold)"
        )
        console.print(
            f"NSSDA §3.2.3, block {_t(st['item'])}: {_t(st['text'])}{warn}", overflow="fold"
        )
    console.print(summary_line(doc))
    unsigned = unsigned_manual_note(records, checker=doc.get("checker"))
    if unsigned:
        console.print(f"[magenta]{_t(unsigned)}[/]", overflow="fold")
    console.print(f"verdict: [bold {colour}]{verdict}[/]")
