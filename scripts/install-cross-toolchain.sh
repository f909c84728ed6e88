#!/usr/bin/env bash
# Installs Debian's Rust toolchain for cross-building the firmware (thumbv6m-none-eabi with
# -Zbuild-std=core) on machines whose rustup cannot add the target.
#
# Idempotent and quiet: when every package is already installed it prints nothing and exits 0.
# Otherwise it runs `apt-get update` and installs only what is missing (root, or sudo).
#
# rustc-web, cargo-web   /usr/bin/rustc and /usr/bin/cargo (1.96)
# rust-web-src           the library source -Zbuild-std compiles core from
# rust-web-llvm, lld-22  /usr/bin/rust-lld (a link to lld-22), the linker rustc uses for thumbv6m
# llvm-22                llvm-objcopy-22, llvm-size-22 and friends for inspecting images
set -euo pipefail

packages=(rustc-web cargo-web rust-web-src rust-web-llvm lld-22 llvm-22)

missing=()
for pkg in "${packages[@]}"; do
    status=$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null || true)
    if [[ "$status" != "install ok installed" ]]; then
        missing+=("$pkg")
    fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
    exit 0
fi

if ! command -v apt-get >/dev/null 2>&1; then
    echo "install-cross-toolchain: missing ${missing[*]}, and this is not a Debian system (no apt-get)." >&2
    echo "install-cross-toolchain: install rustup and run 'rustup target add thumbv6m-none-eabi' instead." >&2
    exit 1
fi

sudo=()
if [[ $(id -u) -ne 0 ]]; then
    sudo=(sudo)
fi

echo "install-cross-toolchain: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update -qq
"${sudo[@]}" apt-get install -y -qq "${missing[@]}" >/dev/null

for tool in /usr/bin/rustc /usr/bin/cargo /usr/bin/rust-lld; do
    if [[ ! -x "$tool" ]]; then
        echo "install-cross-toolchain: $tool is still missing after the install" >&2
        exit 1
    fi
done
