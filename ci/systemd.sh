#!/usr/bin/env bash
# The service files as a drone gets them: deploy/install.sh into a staging root (the binaries of
# the test build), then `systemd-analyze verify` on the installed unit, its paths pointed into the
# staging root. Any complaint (an unknown key, a missing executable) fails.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/deckwatch-target}"
BIN_DIR="${1:-$CARGO_TARGET_DIR/debug}"
STAGE="$(mktemp -d)"
trap 'rm -rf "$STAGE"' EXIT
if ! command -v systemd-analyze >/dev/null; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq systemd >/dev/null
fi
DESTDIR="$STAGE/root" deploy/install.sh --bin-dir "$BIN_DIR" --no-systemctl
unit="$STAGE/deckwatch.service"
sed -e "s#/opt/deckwatch#$STAGE/root/opt/deckwatch#g" \
    -e "s#/var/lib/deckwatch#$STAGE/root/var/lib/deckwatch#g" \
    "$STAGE/root/etc/systemd/system/deckwatch.service" > "$unit"
out=$(systemd-analyze verify "$unit" 2>&1) || { echo "$out" >&2; exit 1; }
if [ -n "$out" ]; then
  echo "systemd-analyze verify: $out" >&2
  exit 1
fi
# Its sandbox: `systemd-analyze security`'s exposure (0 safest, 10 none) must stay "OK" (at most
# 3.0; 1.8 when written, 9.2 before the hardening: BENCHMARKS).
exposure=$(systemd-analyze security --offline=true "$unit" 2>/dev/null \
  | sed -n 's/.*Overall exposure level for [^:]*: \([0-9.]*\).*/\1/p')
if [ -z "$exposure" ] || ! awk -v e="$exposure" 'BEGIN { exit !(e <= 3.0) }'; then
  systemd-analyze security --offline=true "$unit" >&2 || true
  echo "deckwatch.service: exposure ${exposure:-unknown}, more than 3.0" >&2
  exit 1
fi
# The configuration it installs is one deckwatch accepts: every section as written, the source
# switched to the simulator (this build may lack libcamera; ci/libcamera.sh tests the camera).
cfg="$STAGE/pipeline.toml"
sed -e "s#/etc/deckwatch#$STAGE/root/etc/deckwatch#g" -e 's#^kind = "libcamera"#kind = "sim"#' \
    "$STAGE/root/etc/deckwatch/pipeline.toml" > "$cfg"
"$BIN_DIR/deckwatch" run --config "$cfg" --print-config >/dev/null
echo "deckwatch.service: verified, exposure $exposure; the Pi 5 configuration parses and validates"
