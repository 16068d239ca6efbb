#!/bin/sh
# Cross-builds deckwatch for the drone's computer (a Raspberry Pi 5: aarch64, 64-bit Raspberry
# Pi OS or Debian) on an x86_64 Debian 12 machine, without rerun (a viewer runs on the ground) and
# without the camera (libcamera >= 0.4 is not in Debian 12's arm64 archive to link against:
# build on the Pi itself for the camera, see deploy/install.sh). Then, when qemu-user is there,
# runs the built launcher under emulation as a check, with an evaluation of detection and both
# estimators on a committed recording.
#
#   deploy/build-aarch64.sh            # binaries in $CARGO_TARGET_DIR (or target)/aarch64-unknown-linux-gnu/release
#
# Needs (Debian 12): apt-get install gcc-aarch64-linux-gnu libc6-dev-arm64-cross [qemu-user]
# and the Rust target: rustup target add aarch64-unknown-linux-gnu (done here when missing).
# Install on the Pi: copy the folder's deckwatch* binaries and this source tree's deploy/ over,
# then `deploy/install.sh --bin-dir DIR --without-libcamera`.
set -eu

target=aarch64-unknown-linux-gnu
cd "$(dirname "$0")/.."

command -v aarch64-linux-gnu-gcc >/dev/null || {
    echo "build-aarch64: aarch64-linux-gnu-gcc missing (apt-get install gcc-aarch64-linux-gnu libc6-dev-arm64-cross)" >&2
    exit 1
}
rustup target list --installed | grep -qx "$target" || rustup target add "$target"

# The linker, and the C compiler of the crates that build C (lz4, zstd).
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
export CC_aarch64_unknown_linux_gnu=aarch64-linux-gnu-gcc
export AR_aarch64_unknown_linux_gnu=aarch64-linux-gnu-ar

cargo build --release --target "$target" --no-default-features -p deckwatch -p deckwatch-runtime --bins

bin="${CARGO_TARGET_DIR:-target}/$target/release"
file "$bin/deckwatch" 2>/dev/null || true
if command -v qemu-aarch64 >/dev/null; then
    # The launcher and a stage start under emulation, and the launcher's checks run.
    qemu-aarch64 -L /usr/aarch64-linux-gnu "$bin/deckwatch" --version
    qemu-aarch64 -L /usr/aarch64-linux-gnu "$bin/deckwatch-decide" --help >/dev/null
    qemu-aarch64 -L /usr/aarch64-linux-gnu "$bin/deckwatch" run --print-config >/dev/null
    # Detection and both estimators on a committed recording (the same figures as on x86_64).
    qemu-aarch64 -L /usr/aarch64-linux-gnu "$bin/deckwatch" eval tests/data/ship-640x480
    echo "build-aarch64: the binaries run under qemu-aarch64"
fi
echo "build-aarch64: binaries in $bin"
