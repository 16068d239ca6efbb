#!/bin/sh
# Renders what a user sees in the rerun viewer on a saved run, as a PNG (docs/viewer.png).
#
#   docs/viewer-screenshot.sh [RUN.rrd] [OUT.png]
#
# Without RUN.rrd it first runs the README's main job with `--rerun save` (60 s). The native
# viewer (rerun-sdk 0.36.3's `rerun`, from ci/peers.sh's venv or PATH) runs on a virtual X
# display (Xvfb, with the Composite extension: without it the window stays black) on Mesa's
# software Vulkan (`--renderer vulkan`; the GL backend fails on this software stack), and
# ImageMagick's `import` takes the picture. Needs (Debian 12):
#   apt-get install xvfb mesa-vulkan-drivers libgl1-mesa-dri imagemagick
# The viewer plays a loaded recording from its start in real time: the picture is taken
# AT_S seconds (default 34: the default scenario's first calm spell, CLEAR) after it opened.
set -eu

rrd=${1:-}
out=${2:-docs/viewer.png}
at_s=${AT_S:-34}
display=${SCREENSHOT_DISPLAY:-:98}

viewer=$HOME/.cache/deckwatch-venv/bin/rerun
[ -x "$viewer" ] || viewer=$(command -v rerun) || {
    echo "viewer-screenshot: no rerun viewer (run ci/peers.sh, or pip install rerun-sdk==0.36.3)" >&2
    exit 1
}
for tool in Xvfb import; do
    command -v "$tool" >/dev/null || {
        echo "viewer-screenshot: $tool missing (apt-get install xvfb imagemagick mesa-vulkan-drivers)" >&2
        exit 1
    }
done

if [ -z "$rrd" ]; then
    work=$(mktemp -d)
    rrd=$work/run.rrd
    cargo run --release -p deckwatch -- run --rerun save "$rrd"
fi
[ -f "$rrd" ] || { echo "viewer-screenshot: $rrd: no such file" >&2; exit 1; }

Xvfb "$display" -screen 0 1600x1000x24 -extension Composite >/dev/null 2>&1 &
xvfb=$!
viewer_pid=
cleanup() {
    [ -n "$viewer_pid" ] && kill "$viewer_pid" 2>/dev/null
    kill "$xvfb" 2>/dev/null
}
trap cleanup EXIT INT TERM
sleep 2
DISPLAY=$display "$viewer" --renderer vulkan "$rrd" >/dev/null 2>&1 &
viewer_pid=$!
sleep "$at_s"
kill -0 "$viewer_pid" 2>/dev/null || { echo "viewer-screenshot: the viewer exited" >&2; exit 1; }
DISPLAY=$display import -window root "$out"
echo "viewer-screenshot: $out (from $rrd, ${at_s} s into playback)"
