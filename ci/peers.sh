#!/usr/bin/env bash
# The test peers nobody here wrote: pymavlink (MAVLink autopilot and ground station, and its
# mavlogdump.py), in a virtual environment at ~/.cache/deckwatch-venv that tests/mavlink_link.rs
# finds by itself. Idempotent; needs python3 (and, on Debian, python3-venv: installed if missing).
set -euo pipefail
VENV="${DECKWATCH_VENV:-$HOME/.cache/deckwatch-venv}"
if ! "$VENV/bin/python3" -c "import pymavlink" 2>/dev/null; then
  if ! python3 -m venv --help >/dev/null 2>&1 || ! python3 -c "import ensurepip" 2>/dev/null; then
    SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq python3 python3-venv >/dev/null
  fi
  rm -rf "$VENV"
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install -q pymavlink==2.4.50
fi
"$VENV/bin/python3" -c "import pymavlink; print('pymavlink', pymavlink.__version__, 'in', '$VENV')"
