#!/usr/bin/env bash
# Install the named Debian/Ubuntu packages that are missing (apt-get update first, only when something is).
# Uses sudo when not root. The other scripts call it: scripts/setup.sh, scripts/dist.sh, scripts/cross_test.sh.
set -euo pipefail
missing=()
for pkg in "$@"; do
    dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
done
((${#missing[@]})) || exit 0
SUDO=""
[ "$(id -u)" = 0 ] || SUDO="sudo"
echo "apt-get install ${missing[*]}" >&2
$SUDO apt-get update -qq
$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
