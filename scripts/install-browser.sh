#!/usr/bin/env bash
# Installs Chromium, the headless browser that tests the live page (host-sim's `page`
# module: `host-sim/tests/page_browser.rs`), from Debian's package `chromium`.
#
# Idempotent and quiet: when /usr/bin/chromium is there it prints nothing and exits 0.
# Otherwise it runs `apt-get update` and installs chromium (root, or sudo).
set -euo pipefail

browser=/usr/bin/chromium

if [[ -x "$browser" ]]; then
    exit 0
fi

if ! command -v apt-get >/dev/null 2>&1; then
    echo "install-browser: this is not a Debian system (no apt-get); install Chromium by hand" >&2
    echo "install-browser: and point BUGBOT_CHROMIUM at it" >&2
    exit 1
fi
sudo=()
if [[ $(id -u) -ne 0 ]]; then
    sudo=(sudo)
fi
echo "install-browser: installing chromium" >&2
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update -qq
"${sudo[@]}" apt-get install -y -qq --no-install-recommends chromium >/dev/null

if [[ ! -x "$browser" ]]; then
    echo "install-browser: $browser is still missing after the install" >&2
    exit 1
fi
