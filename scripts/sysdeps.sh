#!/usr/bin/env bash
# Install the system libraries orthospec needs when they are missing (WeasyPrint: Pango, HarfBuzz;
# reports: poppler-utils for pdftoppm in tests; ledger tests: PostgreSQL server). Stops with a clear
# message when it cannot.
set -euo pipefail
need=()
ldconfig -p 2>/dev/null | grep -q 'libpango-1.0.so' || need+=(libpango-1.0-0 libpangoft2-1.0-0 libharfbuzz0b libharfbuzz-subset0)
ldconfig -p 2>/dev/null | grep -q 'libharfbuzz-subset.so' || need+=(libharfbuzz-subset0)
command -v pdftoppm >/dev/null 2>&1 || need+=(poppler-utils)
# gdalinfo: the radiometry tests compare with `gdalinfo -stats -hist`; the benchmark times it
command -v gdalinfo >/dev/null 2>&1 || need+=(gdal-bin)
fc-list 2>/dev/null | grep -qi 'dejavu' || need+=(fonts-dejavu-core fontconfig)
# ledger tests start a throw-away PostgreSQL server (initdb/pg_ctl) on 127.0.0.1
compgen -G '/usr/lib/postgresql/*/bin/initdb' >/dev/null || need+=(postgresql)
if [ ${#need[@]} -eq 0 ]; then exit 0; fi
if [ "$(id -u)" != 0 ]; then
  echo "orthospec needs system packages: ${need[*]}; install them (apt-get install ${need[*]}) and retry." >&2
  exit 1
fi
echo "installing system packages: ${need[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq >/dev/null
apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
