#!/usr/bin/env bash
# Installs Node.js and npm, which run the emulator harness (tests/emulator: rp2040js, from
# its package-lock.json by `npm ci`), from Debian's packages.
#
# Idempotent and quiet: when `node` (18 or later) and `npm` are on PATH it prints nothing
# and exits 0. Otherwise it runs `apt-get update` and installs nodejs and npm (root, or sudo).
set -euo pipefail

node_major() {
    node --version 2>/dev/null | sed -n 's/^v\([0-9]*\)\..*/\1/p'
}

major=$(node_major || true)
if [[ -n "$major" && "$major" -ge 18 ]] && command -v npm >/dev/null 2>&1; then
    exit 0
fi

if ! command -v apt-get >/dev/null 2>&1; then
    echo "install-node: this is not a Debian system (no apt-get); install Node.js 18+ and npm by hand" >&2
    exit 1
fi
sudo=()
if [[ $(id -u) -ne 0 ]]; then
    sudo=(sudo)
fi
echo "install-node: installing nodejs and npm" >&2
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update -qq
"${sudo[@]}" apt-get install -y -qq --no-install-recommends nodejs npm >/dev/null

major=$(node_major || true)
if [[ -z "$major" || "$major" -lt 18 ]] || ! command -v npm >/dev/null 2>&1; then
    echo "install-node: node 18+ and npm are still missing after the install" >&2
    exit 1
fi
