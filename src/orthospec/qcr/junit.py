"""junit.xml: one testsuite per rule, one testcase per item (CI systems render it natively).
"""

from __future__ import annotations

import itertools
from collections import Counter as _Counter
from collections.abc import Iterable, Iterator, Mapping
from typing import Any
from xml.sax.saxutils import escape as _escape
from xml.sax.saxutils import quoteattr as _quoteattr

from .. import verdicts as V
from .blocks import _Block, _merged, _rule_parts
from .cells import _XML_SPECIAL, xml_text
from .records import all_records


def _junit_head(doc: Mapping[str, Any]) -> str:
    s = doc["summary"]
    return (
        "\n".join(
            [
                '<?xml version="1.0" encoding="UTF-8"?>',
                f'<testsuites name={_xml_attr("orthospec " + doc["profile"]["id"])} tests="{s["records"]}" '
                f'failures="{s[V.FAIL] + s[V.MISSING] + (s[V.WARN] if doc["fail_on"] == V.WARN else 0)}" '
                f'errors="{s[V.ERROR]}" skipped="{s[V.NOT_APPLICABLE] + s[V.WAIVED]}">',
            ]
        )
        + "\n"
    )


def _xml_attr(v: Any) -> str:
    return _quoteattr(xml_text(v))


def _junit_suite(rid: str, tests: int, fails: int, errs: int, skipped: int) -> str:
    return (
        f'  <testsuite name={_xml_attr(rid)} tests="{tests}" failures="{fails}" '
        f'errors="{errs}" skipped="{skipped}">'
    )


def _junit_case(rid: str, r: Mapping[str, Any], fail_on: str) -> str:
    """One record's testcase."""
    name = _xml_attr(f"{rid}[{r['item']}]")
    cls = _xml_attr(f"{r['scope']}.{rid}")
    v = r["verdict"]
    if v in (V.FAIL, V.MISSING) or (v == V.WARN and fail_on == V.WARN):
        body = _escape(xml_text(f"{r['title']} — {r['requirement'].get('text', '')}"))
        # the checker's own open work (consequence incomplete, an unsigned manual check) is told
        # apart from a failure of the contractor's products
        kind = (
            V.INCOMPLETE
            if r.get("consequence") == V.INCOMPLETE or (r.get("manual") and v == V.MISSING)
            else v
        )
        return (
            f"    <testcase name={name} classname={cls}>{_junit_reason(r)}<failure "
            f'message={_xml_attr(r["message"])} type="{kind}">{body}</failure></testcase>'
        )
    if v == V.ERROR:
        body = _escape(xml_text(f"{r['title']} — {r['requirement'].get('text', '')}"))
        return (
            f"    <testcase name={name} classname={cls}>{_junit_reason(r)}<error "
            f'message={_xml_attr(r["message"])} type="error">{body}</error></testcase>'
        )
    if v in V.NEUTRAL:
        return f"    <testcase name={name} classname={cls}><skipped message={_xml_attr(r['message'])}/></testcase>"
    return f"    <testcase name={name} classname={cls}/>"


def _junit_reason(r: Mapping[str, Any]) -> str:
    """The record's reason code as a testcase property (CI tools group failures by it), "" without one."""
    why = r.get("reason")
    return (
        f'<properties><property name="reason" value={_xml_attr(str(why))}/></properties>'
        if why
        else ""
    )


def _counts(verdicts: Iterable[str] | _Counter[str]) -> tuple[int, int, int]:
    """(failures, errors, skipped) of a testsuite, as JUnit counts them (from the verdicts, or
    their counts)."""
    fails = errs = skipped = 0
    for v, k in (verdicts if isinstance(verdicts, _Counter) else _Counter(verdicts)).items():
        fails += k if v in (V.FAIL, V.MISSING) else 0
        errs += k if v == V.ERROR else 0
        skipped += k if v in V.NEUTRAL else 0
    return fails, errs, skipped


def _junit_block_cases(
    rid: str, block: _Block, a: int, b: int, fail_on: str, plain: bool
) -> list[str] | str:
    """Testcases of compact items a..b-1: passes as one string operation per item when the rule id
    and the ids need no escaping (``plain``; every item a pass: the lines as one text, by slice
    assignment), any other verdict through :func:`_junit_case`."""
    rule = block.rule
    items = block.items[a:b]
    verdicts = block.verdict.part(a, b)
    cls = _xml_attr(f"{rule.get('scope', '')}.{rid}")
    if plain and verdicts is None and block.verdict.const == V.PASS:
        n = len(items)
        flat: list[str] = [""] * (3 * n)
        flat[0::3] = [f'    <testcase name="{rid}['] * n
        flat[1::3] = items
        flat[2::3] = [f']" classname={cls}/>\n'] * n
        return "".join(flat)
    vs = list(block.verdict.get(a, b))
    need = [k for k, v in enumerate(vs) if v != V.PASS or not plain]
    msgs: dict[int, str] = {}
    if need:
        allm = block.messages(a, b)
        reqs = list(block.req_texts(a, b))
        msgs = {k: allm[k] if isinstance(allm, list) else allm for k in need}
    out = []
    for k, (it, v) in enumerate(zip(items, vs, strict=True)):
        if v == V.PASS and plain:
            out.append(f'    <testcase name="{rid}[{it}]" classname={cls}/>')
        else:
            r = {
                "item": it,
                "scope": rule.get("scope", ""),
                "verdict": v,
                "message": msgs[k],
                "title": rule.get("title", ""),
                "requirement": {"text": reqs[k]},
            }
            out.append(_junit_case(rid, r, fail_on))
    return out


def _iter_junit_records(doc: Mapping[str, Any]) -> Iterator[str]:
    """junit.xml record by record through :func:`all_records`: the reference :func:`iter_junit`
    matches byte for byte, and the path for version 1 documents."""
    yield _junit_head(doc)
    for rid, group in itertools.groupby(all_records(doc), key=lambda r: r["rule"]):
        recs = list(group)
        fails, errs, skipped = _counts(r["verdict"] for r in recs)
        out = [_junit_suite(rid, len(recs), fails, errs, skipped)]
        out.extend(_junit_case(rid, r, doc["fail_on"]) for r in recs)
        out.append("  </testsuite>")
        yield "\n".join(out) + "\n"
    yield "</testsuites>\n"


def iter_junit(doc: Mapping[str, Any]) -> Iterator[str]:
    """junit.xml as a stream of pieces: one testsuite per rule, its counts from the stored records'
    verdicts and the compact verdict column, its testcases a slice of items at a time (no list of
    a rule's records; the same bytes as :func:`_iter_junit_records`).

    Every text passes :func:`xml_text`, so control characters in delivery ids keep it well-formed."""
    rids = [r["rule"] for r in doc.get("rules") or []]
    if "compact" not in doc or len(set(rids)) != len(rids):
        yield from _iter_junit_records(doc)
        return
    fail_on = doc["fail_on"]
    yield _junit_head(doc)
    rest: list[Mapping[str, Any]] = []
    for summary, full, block in _rule_parts(doc):
        if summary is None:
            rest.extend(full)
            continue
        rid = summary["rule"]
        n = block.n if block is not None else 0
        if not full and not n:
            continue
        verdicts = [r["verdict"] for r in full]
        if block is not None:
            col = block.verdict.part(0, n)
            verdicts.extend(col if col is not None else [block.verdict.const])  # one stands for n
        counted = _Counter(verdicts)
        if block is not None and block.verdict.values is None:
            counted[block.verdict.const] += n - 1
        fails, errs, skipped = _counts(counted)
        del verdicts, counted
        out = [_junit_suite(rid, len(full) + n, fails, errs, skipped)]
        plain = block is not None and not _XML_SPECIAL.search(rid) and block.items_plain_xml()
        for part in _merged(summary, full, block):
            if isinstance(part, dict):
                out.append(_junit_case(rid, part, fail_on))
            else:
                assert block is not None
                cases = _junit_block_cases(rid, block, *part, fail_on, plain)
                if isinstance(cases, str):  # whole lines already
                    if out:
                        yield "\n".join(out) + "\n"
                    yield cases
                else:
                    out.extend(cases)
                    yield "\n".join(out) + "\n"
                out = []
        out.append("  </testsuite>")
        yield "\n".join(out) + "\n"
    if rest:
        for rid, group in itertools.groupby((dict(r) for r in rest), key=lambda r: r["rule"]):
            recs = list(group)
            fails, errs, skipped = _counts(r["verdict"] for r in recs)
            out = [_junit_suite(rid, len(recs), fails, errs, skipped)]
            out.extend(_junit_case(rid, r, fail_on) for r in recs)
            out.append("  </testsuite>")
            yield "\n".join(out) + "\n"
    yield "</testsuites>\n"
