#!/usr/bin/env bash
# Installs the MAVLink test peer's npm packages exactly as package-lock.json pins them. Idempotent: a
# node_modules that already matches the lockfile is left alone.
set -euo pipefail
cd "$(dirname "$0")"
command -v npm >/dev/null || { echo "mavlink_peer: npm not found (install nodejs and npm)" >&2; exit 1; }
if [ -f node_modules/.package-lock.json ] && cmp -s package-lock.json node_modules/.vantage-lock; then
  echo "mavlink_peer: npm packages present"
  exit 0
fi
npm ci --no-audit --no-fund --loglevel=error
cp package-lock.json node_modules/.vantage-lock
