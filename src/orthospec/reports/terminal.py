"""The rich terminal summary of a check: verdict, counts, failing rules with offending items."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

MAX_ITEMS = 8
_STYLE = {"pass": "green", "fail": "bold red", "warn": "yellow", "missing": "magenta",
          "error": "bold red", "waived": "cyan", "not_applicable": "dim"}


def summary_line(doc: dict[str, Any]) -> str:
    s = doc["summary"]
    return (f"{s['rules']} rules, {s['records']} records: {s['pass']} passed, {s['warn']} warned, "
            f"{s['fail']} failed, {s['waived']} waived, {s['missing']} missing, "
            f"{s['not_applicable']} not applicable, {s['error']} errors")


def render(doc: dict[str, Any], console: Console, *, max_items: int = MAX_ITEMS, verbose: bool = False) -> None:
    p, d = doc["profile"], doc["delivery"]
    verdict = doc["verdict"].upper()
    colour = "green" if doc["verdict"] == "accepted" else "red"
    console.print(f"[bold]orthospec[/] {escape(d['path'])} against {escape(p['id'])} {escape(p['version'])} "
                  f"(sha256 {p['sha256'][:12]}…), {doc['date']}")
    shown_rules = [r for r in doc["rules"] if verbose or r["verdict"] not in ("pass", "not_applicable")]
    id_width = max((len(r["rule"]) for r in shown_rules), default=4)
    t = Table(show_header=True, header_style="bold", box=None, pad_edge=False)
    t.add_column("verdict", no_wrap=True, min_width=7)
    t.add_column("rule", no_wrap=True, min_width=id_width)  # ids are what auditors search for: never cut
    t.add_column("scope", no_wrap=True)
    t.add_column("clause", no_wrap=True)
    t.add_column("items / reason", ratio=1)
    shown = 0
    for r in doc["rules"]:
        v = r["verdict"]
        if v in ("pass", "not_applicable") and not verbose:
            continue
        off = r["offending"]
        items = ", ".join(off[:max_items]) + (f" … (+{len(off) - max_items} more)" if len(off) > max_items else "")
        if v == "waived":
            items = f"{r['counts'].get('waived', 0)} waived"
        if r.get("error"):
            items = r["error"]
        t.add_row(f"[{_STYLE.get(v, '')}]{v}[/]", escape(r["rule"]), r["scope"],
                  escape(r.get("clause_ref") or r["clause"]), escape(items))
        shown += 1
    if shown:
        console.print(t)
    for reason in doc["rollup"]["reasons"]:
        console.print(f"  [red]•[/] {escape(reason)}")
    console.print(summary_line(doc))
    console.print(f"verdict: [bold {colour}]{verdict}[/]")
