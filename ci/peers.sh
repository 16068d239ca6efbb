#!/usr/bin/env bash
# The test peers nobody here wrote: pymavlink (MAVLink autopilot and ground station, and its
# mavlogdump.py), the `mcap` reader (flight recordings), rerun-sdk's `rerun` command (which
# converts and verifies them) and OpenCV (bench/opencv_pose_baseline.py: a detection and pose
# baseline) and Ray with matplotlib (cluster/run_trials.py: the trials on a cluster, and its
# plot), in a virtual environment at ~/.cache/deckwatch-venv that the tests find by themselves. Idempotent; needs python3 (and, on Debian, python3-venv: installed if missing).
set -euo pipefail
VENV="${DECKWATCH_VENV:-$HOME/.cache/deckwatch-venv}"
PEERS="pymavlink==2.4.50 mcap==1.6.0 rerun-sdk==0.36.3 opencv-python-headless==5.0.0.93 ray==2.60.0 matplotlib==3.11.2"
if ! "$VENV/bin/python3" -c "import pymavlink, mcap, rerun, cv2, ray, matplotlib" 2>/dev/null; then
  if ! python3 -m venv --help >/dev/null 2>&1 || ! python3 -c "import ensurepip" 2>/dev/null; then
    SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq python3 python3-venv >/dev/null
  fi
  [ -x "$VENV/bin/pip" ] || python3 -m venv "$VENV"
  "$VENV/bin/pip" install -q $PEERS
fi
"$VENV/bin/python3" -c "import pymavlink, mcap, rerun, cv2, ray, matplotlib; print('pymavlink', pymavlink.__version__, 'mcap', mcap.__version__, 'rerun-sdk', rerun.__version__, 'opencv', cv2.__version__, 'ray', ray.__version__, 'matplotlib', matplotlib.__version__, 'in', '$VENV')"
