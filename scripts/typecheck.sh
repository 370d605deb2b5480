#!/usr/bin/env bash
# mypy over src/ under pyproject.toml [tool.mypy], as a ratchet (run by `make lint`).
#
# ALLOWED is the number of errors the tree still has (issue 28: 297 with pandas-stubs at the start of
# the pass); the check fails when there are more, so no change adds a type error, and it asks for
# the number to be lowered when there are fewer (without failing: a merge that fixes
# some must not break CI). The goal is 0: with ALLOWED=0 this is plain `mypy src` (any error fails).
set -uo pipefail
cd "$(dirname "$0")/.."
ALLOWED=0
MYPY="${MYPY:-.venv/bin/mypy}"
if [ "$ALLOWED" -eq 0 ]; then
  exec "$MYPY" src
fi
out="$("$MYPY" src 2>&1)"
status=$?
count=$(grep -c ': error:' <<<"$out" || true)
if [ "$status" -ne 0 ] && [ "$count" -eq 0 ]; then
  echo "$out"; echo "mypy did not run (exit $status)"; exit 2
fi
if [ "$count" -gt "$ALLOWED" ]; then
  echo "$out" | grep ': error:'
  echo "mypy: $count errors, more than the $ALLOWED allowed (scripts/typecheck.sh): fix the new ones"
  exit 1
fi
if [ "$count" -lt "$ALLOWED" ]; then
  echo "mypy: $count errors, fewer than the $ALLOWED allowed: lower ALLOWED in scripts/typecheck.sh to $count"
  exit 0
fi
echo "mypy: $count errors (the ratchet's $ALLOWED; 0 is the goal)"
