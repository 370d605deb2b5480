#!/usr/bin/env bash
# Install the system libraries orthospec needs when they are missing (WeasyPrint: Pango, HarfBuzz;
# reports: poppler-utils for pdftoppm in tests; ledger tests: PostgreSQL server). Stops with a clear
# message when it cannot.
#
# Each probe's output is captured whole and matched in bash, never piped into `grep -q`: under
# `pipefail` grep's early exit kills the lister with SIGPIPE once its output passes the pipe buffer
# (64 KiB; `ldconfig -p` does on a machine with many libraries), and installed packages were then
# reported missing at random (tests/test_sysdeps.py runs this script 100 times).
set -euo pipefail
libs=$(ldconfig -p 2>/dev/null || true)
fonts=$(fc-list 2>/dev/null || true)
has_lib() { [[ $libs == *"$1"* ]]; }
need=()
has_lib 'libpango-1.0.so' || need+=(libpango-1.0-0 libpangoft2-1.0-0 libharfbuzz0b libharfbuzz-subset0)
has_lib 'libharfbuzz-subset.so' || need+=(libharfbuzz-subset0)
command -v pdftoppm >/dev/null 2>&1 || need+=(poppler-utils)
# gdalinfo: the radiometry tests compare with `gdalinfo -stats -hist`; the benchmark times it
command -v gdalinfo >/dev/null 2>&1 || need+=(gdal-bin)
[[ ${fonts,,} == *dejavu* ]] || need+=(fonts-dejavu-core fontconfig)
# ledger signatures: ssh-keygen -Y sign / verify (OpenSSH 8.2+)
command -v ssh-keygen >/dev/null 2>&1 || need+=(openssh-client)
# ledger tests start a throw-away PostgreSQL server (initdb/pg_ctl) on 127.0.0.1
compgen -G '/usr/lib/postgresql/*/bin/initdb' >/dev/null || need+=(postgresql)
# the interactive report's browser test drives Debian's Chromium headless (issue 30)
command -v chromium >/dev/null 2>&1 || need+=(chromium)
command -v chromedriver >/dev/null 2>&1 || need+=(chromium-driver)
if [ ${#need[@]} -eq 0 ]; then exit 0; fi
# one name once, in a stable order
mapfile -t need < <(printf '%s\n' "${need[@]}" | sort -u)
if [ "$(id -u)" != 0 ]; then
  echo "orthospec needs system packages: ${need[*]}; install them (apt-get install ${need[*]}) and retry." >&2
  exit 1
fi
echo "installing system packages: ${need[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq >/dev/null
apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
