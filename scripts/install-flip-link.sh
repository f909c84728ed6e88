#!/usr/bin/env bash
# Installs flip-link, the firmware's linker wrapper (firmware/.cargo/config.toml): it puts
# the stack below .data and .bss, so a stack overflow hits the end of RAM and faults
# instead of silently overwriting statics. It calls `rust-lld`, which rustup's toolchain
# puts in the linker's PATH and Debian's rust-web-llvm installs as /usr/bin/rust-lld.
#
#   install-flip-link.sh        prints the path of the flip-link binary on stdout
#
# Idempotent and quiet: when FLIP_LINK_VERSION is already installed in cargo's bin directory
# ($CARGO_HOME/bin, else ~/.cargo/bin) it only prints that path. Otherwise it builds it from
# crates.io with the host's cargo (`cargo install --locked`), reporting on stderr.
# Under `cargo xtask`, CARGO names the cargo that runs it; a bare `cargo` otherwise.
set -euo pipefail

FLIP_LINK_VERSION=0.1.12

bin_dir="${CARGO_HOME:-$HOME/.cargo}/bin"
flip_link="$bin_dir/flip-link"

cargo="${CARGO:-cargo}"

# flip-link has no --version: cargo's own record says which version the binary is.
installed() {
    [[ -x "$flip_link" ]] &&
        "$cargo" install --list 2>/dev/null | grep -qx "flip-link v$FLIP_LINK_VERSION:"
}

if installed; then
    echo "$flip_link"
    exit 0
fi

echo "install-flip-link: cargo install --locked flip-link@$FLIP_LINK_VERSION" >&2
# --force: cargo's record may list a binary that has since been removed by hand.
"$cargo" install --quiet --locked --force "flip-link@$FLIP_LINK_VERSION" >&2

if ! installed; then
    echo "install-flip-link: $flip_link is still not flip-link $FLIP_LINK_VERSION after the install" >&2
    exit 1
fi
echo "$flip_link"
