#!/usr/bin/env bash
# deckwatch's libcamera capture, built and tested against libcamera's `virtual` camera.
#
# Debian 12 has libcamera 0.0.3; the `libcamera` crate needs >= 0.4. So a minimal Debian 13
# (trixie, libcamera 0.4) root is debootstrapped once, and the workspace is built and tested in
# a chroot of it with the host's Rust toolchain bind-mounted (read-only). The virtual camera
# plays simulator-rendered JPEGs of the deck, so the test runs
# libcamera -> capture -> detect -> estimate -> decide as real processes over iceoryx2 and
# checks each attitude against the rendered truth.
#
# Usage (as root, from anywhere):
#   ci/libcamera.sh            set up (once), build, run the test          (what .ci/run calls)
#   ci/libcamera.sh build      set up and build only
#   ci/libcamera.sh shell CMD  run CMD in the project folder inside the chroot (after a build)
#
# Variables (optional):
#   DECKWATCH_LIBCAMERA_ROOT  where the chroot and its build output live
#                             (default ~/.cache/deckwatch-libcamera; reused between runs)
#   MIRROR                    Debian mirror (default: the host's first apt `URIs:` entry)
#
# Changes nothing on the host outside DECKWATCH_LIBCAMERA_ROOT but crates downloaded into
# CARGO_HOME; every mount below the chroot is undone on exit.
set -euo pipefail

PROJECT=$(cd "$(dirname "$0")/.." && pwd)
WORK=${DECKWATCH_LIBCAMERA_ROOT:-$HOME/.cache/deckwatch-libcamera}
ROOT=$WORK/trixie
MIRROR=${MIRROR:-$(awk '/^URIs:/{print $2; exit}' /etc/apt/sources.list.d/*.sources 2>/dev/null || true)}
MIRROR=${MIRROR:-http://deb.debian.org/debian}
export CARGO_HOME=${CARGO_HOME:-$HOME/.cargo}
export RUSTUP_HOME=${RUSTUP_HOME:-$HOME/.rustup}
# Build output stays inside the chroot: it links against trixie's libraries, not the host's.
TARGET=/build/target
MODE=${1:-test}

t0=$SECONDS
step() { echo "=== libcamera [+$((SECONDS - t0))s] $*"; }
die() { echo "ci/libcamera.sh: $*" >&2; exit 1; }

[ "$(id -u)" = 0 ] || die "needs root (debootstrap, chroot, mounts)"
command -v rustup >/dev/null || die "needs rustup (the host's toolchain is used inside the chroot)"
mkdir -p "$WORK" "$CARGO_HOME"

# --- 1. trixie root (once): debootstrap from the host or from its unpacked .deb ---------------
if [ ! -e "$ROOT/.stamp-bootstrap" ]; then
    if command -v debootstrap >/dev/null; then
        DEBOOTSTRAP=debootstrap
    else
        rm -rf "$WORK/tools" && mkdir -p "$WORK/tools"
        (cd "$WORK/tools" &&
            { timeout 120 apt-get download debootstrap 2>/dev/null ||
                { timeout 300 apt-get update -qq && timeout 120 apt-get download debootstrap; }; } &&
            dpkg -x debootstrap_*.deb root) || die "could not fetch debootstrap"
        export DEBOOTSTRAP_DIR=$WORK/tools/root/usr/share/debootstrap
        DEBOOTSTRAP=$WORK/tools/root/usr/sbin/debootstrap
    fi
    step "debootstrap trixie from $MIRROR into $ROOT"
    rm -rf "$ROOT"
    timeout 1200 "$DEBOOTSTRAP" --variant=minbase trixie "$ROOT" "$MIRROR" >"$WORK/debootstrap.log" 2>&1 ||
        { tail -20 "$WORK/debootstrap.log"; die "debootstrap failed (log: $WORK/debootstrap.log)"; }
    touch "$ROOT/.stamp-bootstrap"
fi

# --- 2. mounts, undone on exit (deepest first) ---------------------------------------------------
cleanup() {
    findmnt -rn -o TARGET | grep -E "^$ROOT(/|$)" | sort -r | while read -r m; do
        umount "$m" 2>/dev/null || umount -l "$m"
    done
}
trap cleanup EXIT
bind() { # bind SRC DST [ro]
    mkdir -p "$2"
    mountpoint -q "$2" || mount --bind "$1" "$2"
    if [ "${3:-}" = ro ]; then mount -o remount,bind,ro "$2"; fi
}
mountpoint -q "$ROOT/proc" || mount -t proc proc "$ROOT/proc"
mountpoint -q "$ROOT/sys" || mount -t sysfs sys "$ROOT/sys"
bind /dev "$ROOT/dev"
bind /dev/pts "$ROOT/dev/pts"
# iceoryx2's shared memory: a tmpfs of the chroot's own, so nothing is shared with the host.
mkdir -p "$ROOT/dev/shm"
mountpoint -q "$ROOT/dev/shm" || mount -t tmpfs -o mode=1777,size=512m shm "$ROOT/dev/shm"

# --- 3. build dependencies inside trixie (once) ---------------------------------------------------
# libclang1-19 + libclang-common-19-dev suffice for bindgen (libclang-dev adds ~300 MB);
# g++ builds libcamera-sys' C++ shim and links.
if [ ! -e "$ROOT/.stamp-packages" ]; then
    step "apt-get install libcamera-dev (trixie) inside the chroot"
    cp /etc/resolv.conf "$ROOT/etc/resolv.conf" 2>/dev/null || true
    timeout 1200 chroot "$ROOT" env DEBIAN_FRONTEND=noninteractive LC_ALL=C bash -c '
        apt-get update -q &&
        apt-get install -y -q --no-install-recommends \
            libcamera-dev libclang1-19 libclang-common-19-dev g++ pkg-config &&
        apt-get clean' >"$WORK/apt.log" 2>&1 ||
        { tail -20 "$WORK/apt.log"; die "apt-get in the chroot failed (log: $WORK/apt.log)"; }
    touch "$ROOT/.stamp-packages"
fi
step "libcamera $(chroot "$ROOT" pkg-config --modversion libcamera) in the chroot"

# --- 4. crates on the host (it has the CA certificates), then an offline build in the chroot ------
TC_BIN=$(cd "$PROJECT" && dirname "$(rustup which rustc)")
step "cargo fetch on the host"
(cd "$PROJECT" && timeout 900 "$TC_BIN/cargo" fetch --locked)
bind "$RUSTUP_HOME" "$ROOT$RUSTUP_HOME" ro
bind "$CARGO_HOME" "$ROOT$CARGO_HOME"
bind "$PROJECT" "$ROOT/deckwatch"
in_chroot() {
    chroot "$ROOT" env -i HOME=/root LC_ALL=C.UTF-8 PATH="$TC_BIN:/usr/bin:/bin" \
        CARGO_HOME="$CARGO_HOME" RUSTUP_HOME="$RUSTUP_HOME" CARGO_TARGET_DIR="$TARGET" \
        CARGO_TERM_COLOR=never CARGO_INCREMENTAL=0 ${EXTRA_ENV:-} \
        bash -c "cd /deckwatch && $1"
}
# Without rerun (the `rerun` feature): the camera path does not need it, and it would add
# ~17 minutes to a clean build. The same packages and features for the binaries and the test.
FEATURES="--no-default-features --features deckwatch-tests/libcamera,deckwatch/libcamera"
PACKAGES="-p deckwatch-tests -p deckwatch -p deckwatch-runtime -p deckwatch-capture -p deckwatch-detect -p deckwatch-estimate -p deckwatch-decide"
step "cargo build in the chroot ($FEATURES)"
in_chroot "timeout 2400 cargo build --offline --locked $PACKAGES $FEATURES --bins --tests"

case "$MODE" in
build) step "built (output in $ROOT$TARGET)"; exit 0 ;;
shell) shift; in_chroot "$*"; exit $? ;;
test) ;;
*) die "unknown mode \`$MODE\` (test, build, shell CMD)" ;;
esac

# The host's clippy cannot see the libcamera code (the feature does not build there).
step "cargo clippy in the chroot ($FEATURES)"
in_chroot "cargo clippy --offline --locked $PACKAGES $FEATURES --all-targets -- -D warnings"

# --- 5. the virtual camera plays a rendered recording ---------------------------------------------
SIM=/var/tmp/deckwatch-virtual-camera
step "render the deck for the virtual camera ($SIM in the chroot)"
in_chroot "rm -rf $SIM && $TARGET/debug/deckwatch sim record --out $SIM --scenario ship --frames 24 \
    --rate 2 --width 640 --height 480 --seed 3 --look clean --virtual-camera deckwatch-virtual"
mkdir -p "$ROOT/usr/share/libcamera/pipeline/virtual"
cp "$ROOT$SIM/virtual/virtual.yaml" "$ROOT/usr/share/libcamera/pipeline/virtual/virtual.yaml"
step "deckwatch cameras"
in_chroot "timeout 60 $TARGET/debug/deckwatch cameras"

step "test: libcamera -> capture -> detect -> estimate -> decide"
EXTRA_ENV="DECKWATCH_VIRTUAL_CAMERA_RECORDING=$SIM DECKWATCH_TEST_BIN_DIR=$TARGET/debug" \
    in_chroot "timeout 900 cargo test --offline --locked $PACKAGES $FEATURES --test libcamera -- --nocapture"
step "done"
