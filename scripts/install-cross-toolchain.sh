#!/usr/bin/env bash
# Installs what cross-building the firmware (thumbv6m-none-eabi) needs from Debian's packages.
#
#   install-cross-toolchain.sh [--rust] [--c]     (no option: both)
#
# --rust  Debian's Rust toolchain, for machines whose rustup cannot add the target (the
#         firmware is then built with -Zbuild-std=core):
#           rustc-web, cargo-web   /usr/bin/rustc and /usr/bin/cargo (1.96)
#           rust-web-src           the library source -Zbuild-std compiles core from
#           rust-web-llvm, lld-22  /usr/bin/rust-lld (a link to lld-22), the linker rustc uses
#           llvm-22                llvm-objcopy-22, llvm-size-22 and friends for inspecting images
#           rust-web-clippy        cargo-clippy, for `cargo xtask lint` on the firmware
# --c     The C toolchain of the firmware's `vl53l5cx` feature (ST's C driver, built by `cc`
#         and bound by `bindgen`), needed with either Rust toolchain:
#           gcc-arm-none-eabi        arm-none-eabi-gcc and -ar, which compile ST's driver
#           libnewlib-arm-none-eabi  the C library headers (/usr/lib/arm-none-eabi/include)
#           libclang-dev             the libclang bindgen loads, with clang's own headers
#
# Idempotent and quiet: when every package is already installed it prints nothing and exits 0.
# Otherwise it runs `apt-get update` and installs only what is missing (root, or sudo).
set -euo pipefail

want_rust=0
want_c=0
for arg in "$@"; do
    case "$arg" in
        --rust) want_rust=1 ;;
        --c) want_c=1 ;;
        *)
            echo "usage: install-cross-toolchain.sh [--rust] [--c]" >&2
            exit 2
            ;;
    esac
done
if [[ $# -eq 0 ]]; then
    want_rust=1
    want_c=1
fi

packages=()
if [[ $want_rust -eq 1 ]]; then
    packages+=(rustc-web cargo-web rust-web-src rust-web-llvm lld-22 llvm-22 rust-web-clippy)
fi
if [[ $want_c -eq 1 ]]; then
    packages+=(gcc-arm-none-eabi libnewlib-arm-none-eabi libclang-dev)
fi

if ! command -v dpkg-query >/dev/null 2>&1 || ! command -v apt-get >/dev/null 2>&1; then
    # Not Debian. A developer who brought their own C cross-compiler (and libclang) can still
    # build with rustup; anything else we cannot install from here.
    if [[ $want_rust -eq 0 ]] && command -v arm-none-eabi-gcc >/dev/null 2>&1; then
        exit 0
    fi
    echo "install-cross-toolchain: this is not a Debian system (no apt-get); install by hand:" >&2
    if [[ $want_rust -eq 1 ]]; then
        echo "install-cross-toolchain:   rustup, then 'rustup target add thumbv6m-none-eabi'" >&2
    fi
    if [[ $want_c -eq 1 ]]; then
        echo "install-cross-toolchain:   arm-none-eabi-gcc with newlib, and libclang" >&2
    fi
    exit 1
fi

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

sudo=()
if [[ $(id -u) -ne 0 ]]; then
    sudo=(sudo)
fi

echo "install-cross-toolchain: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update -qq
"${sudo[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null

tools=()
if [[ $want_rust -eq 1 ]]; then
    tools+=(/usr/bin/rustc /usr/bin/cargo /usr/bin/rust-lld /usr/bin/cargo-clippy)
fi
if [[ $want_c -eq 1 ]]; then
    tools+=(/usr/bin/arm-none-eabi-gcc /usr/bin/arm-none-eabi-ar
        /usr/lib/arm-none-eabi/include/string.h)
fi
for tool in "${tools[@]}"; do
    if [[ ! -e "$tool" ]]; then
        echo "install-cross-toolchain: $tool is still missing after the install" >&2
        exit 1
    fi
done
