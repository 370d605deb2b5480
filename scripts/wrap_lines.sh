#!/usr/bin/env bash
# Wrap the lines longer than LIMIT (default 100) with `ruff format`, touching nothing else.
#
# `ruff format` over the tree would rewrite ~300 files (quotes, trailing commas, every statement it
# would lay out differently): every open branch would conflict. This runs it with `--range` on each
# statement that holds a line over the limit, bottom-up in each file (so line numbers above stay
# valid), and prints the counts before and after. Run it once, on main, after the merges:
#
#   bash scripts/wrap_lines.sh [LIMIT]      # then review `git diff --stat`, run the tests, commit
#
# Lines ruff cannot wrap (long strings, URLs, comments) remain; enable E501 at a limit the tree then
# meets (pyproject.toml [tool.ruff.lint] ignore), or fix the rest by hand.
set -euo pipefail
cd "$(dirname "$0")/.."
LIMIT="${1:-100}"
RUFF="${RUFF:-.venv/bin/ruff}"
DIRS=(src tests benchmarks examples scripts)

count() {
  { "$RUFF" check --select E501 --line-length "$1" --output-format concise --quiet "${DIRS[@]}" 2>/dev/null || true; } \
    | grep -c ': E501 ' || true
}

before=$(count "$LIMIT")
# file:line of every long line, grouped by file, the last line first
{ "$RUFF" check --select E501 --line-length "$LIMIT" --output-format concise --quiet "${DIRS[@]}" 2>/dev/null || true; } \
  | awk -F: '/: E501 /{print $1 "\t" $2}' | sort -t$'\t' -k1,1 -k2,2nr > "${TMPDIR:-/tmp}/wrap_lines.$$"

trap 'rm -f "${TMPDIR:-/tmp}/wrap_lines.$$"' EXIT
while IFS=$'\t' read -r file line; do
  # a range that does not start a statement is widened by ruff to the enclosing one
  "$RUFF" format --quiet --line-length "$LIMIT" --range "$line:$line" "$file" || true
done < "${TMPDIR:-/tmp}/wrap_lines.$$"
after=$(count "$LIMIT")
echo "lines over $LIMIT characters: $before before, $after after (git diff --stat to review)"
