#!/usr/bin/env bash
# Installs deckwatch as a service on the drone's computer (a Raspberry Pi 5 with Debian/Raspberry
# Pi OS, aarch64; any systemd Linux works): the binaries in /opt/deckwatch/bin (the launcher starts
# the stages from its own folder), a `deckwatch` user in the video and dialout groups, the
# configuration in /etc/deckwatch (kept if it exists), the flight recordings in /var/lib/deckwatch,
# and deckwatch.service, enabled.
#
# Usage (from the source tree, as root):
#   deploy/install.sh                    # builds (release, without rerun: a short build on a Pi)
#   deploy/install.sh --bin-dir DIR      # binaries built elsewhere (a cross build: README)
#   DESTDIR=/tmp/root deploy/install.sh --bin-dir DIR --no-systemctl   # into a staging root
# Then: systemctl start deckwatch; journalctl -u deckwatch -f.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN_DIR=""
SYSTEMCTL=1
FEATURES="--no-default-features --features deckwatch-capture/libcamera,deckwatch/libcamera"
while [ $# -gt 0 ]; do
  case "$1" in
    --bin-dir) BIN_DIR="$2"; shift 2 ;;
    --no-systemctl) SYSTEMCTL=0; shift ;;
    --without-libcamera) FEATURES="--no-default-features"; shift ;;
    *) echo "install.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
ROOT="${DESTDIR:-}"
# The launcher and a binary per process of the pipeline (runtime/src/bin: one file each).
BINARIES="deckwatch $(for f in runtime/src/bin/deckwatch-*.rs; do basename "$f" .rs; done | tr '\n' ' ')"
if [ -z "$BIN_DIR" ]; then
  # shellcheck disable=SC2086
  cargo build --release --locked --workspace --bins $FEATURES
  BIN_DIR="${CARGO_TARGET_DIR:-target}/release"
fi
for b in $BINARIES; do
  [ -x "$BIN_DIR/$b" ] || { echo "install.sh: $BIN_DIR/$b is missing" >&2; exit 1; }
done
if [ -z "$ROOT" ] && ! id deckwatch >/dev/null 2>&1; then
  useradd --system --home-dir /var/lib/deckwatch --shell /usr/sbin/nologin deckwatch
fi
install -d "$ROOT/opt/deckwatch/bin" "$ROOT/etc/deckwatch" "$ROOT/var/lib/deckwatch" "$ROOT/etc/systemd/system"
for b in $BINARIES; do
  install -m 0755 "$BIN_DIR/$b" "$ROOT/opt/deckwatch/bin/$b"
done
install -m 0644 README.md "$ROOT/opt/deckwatch/README.md"
[ -e "$ROOT/etc/deckwatch/pipeline.toml" ] || install -m 0644 deploy/pi5-camera-module-3.toml "$ROOT/etc/deckwatch/pipeline.toml"
[ -e "$ROOT/etc/deckwatch/camera-module-3-2304x1296/camera.json" ] ||
  install -D -m 0644 deploy/camera-module-3-2304x1296/camera.json "$ROOT/etc/deckwatch/camera-module-3-2304x1296/camera.json"
install -m 0644 deploy/systemd/deckwatch.service "$ROOT/etc/systemd/system/deckwatch.service"
[ -z "$ROOT" ] && chown deckwatch:deckwatch /var/lib/deckwatch
install -d "$ROOT/usr/local/bin"
ln -sf /opt/deckwatch/bin/deckwatch "$ROOT/usr/local/bin/deckwatch"
if [ "$SYSTEMCTL" = 1 ] && [ -z "$ROOT" ]; then
  systemctl daemon-reload
  systemctl enable deckwatch.service
  echo "installed; start with: systemctl start deckwatch (journalctl -u deckwatch -f)"
else
  echo "installed into ${ROOT:-/}"
fi
