#!/usr/bin/env bash
# The flight recorder's cost (BENCHMARKS.md, "Flight recorder"): the pipeline replays a
# 3280x2464 recording at 10 and 30 fps for 20 s each, without a recorder, recording every frame
# raw (foxglove.RawImage, lz4 chunks) and compressed (foxglove.CompressedImage, JPEG q90), one
# after the other in one run. Prints per run: end-to-end latency p50/p99, drops, and the
# recorder's own line (frames written/dropped, MB/s, CPU).
# Usage: bench/record.sh [RECORDING] (default: renders 60 frames into /tmp/deckwatch-bench60).
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/deckwatch-target}"
cargo build --quiet --release --no-default-features -p deckwatch -p deckwatch-runtime --bins
BIN="$CARGO_TARGET_DIR/release"
REC="${1:-/tmp/deckwatch-bench60}"
if [ ! -d "$REC" ]; then
  "$BIN/deckwatch" sim record --frames 60 --out "$REC" >/dev/null
fi
OUT="$(mktemp -d)"
trap 'rm -rf "$OUT"' EXIT
printf '[record]\nframes = "raw"\ncompression = "lz4"\n' > "$OUT/raw.toml"
printf '[record]\nframes = "jpeg"\njpeg_quality = 90\ncompression = "none"\n' > "$OUT/jpeg.toml"
printf '' > "$OUT/none.toml"
printf '%-5s %-5s %9s %9s %6s  %s\n' fps mode "e2e p50" "e2e p99" drops recorder
for rate in 10 30; do
  frames=$((rate * 20))
  for mode in none raw jpeg; do
    args=(latency "$REC" --rate "$rate" --frames "$frames" --json --config "$OUT/$mode.toml")
    [ "$mode" != none ] && args+=(--record "$OUT/$mode.mcap")
    "$BIN/deckwatch" "${args[@]}" >"$OUT/report.json" 2>"$OUT/stderr"
    line=$(grep -o 'deckwatch-record: .*frames written.*' "$OUT/stderr" | sed 's/^deckwatch-record: [^:]*: //' || true)
    python3 - "$OUT/report.json" "$rate" "$mode" "$line" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
e2e = next(l for l in r["latency"] if l["interval"] == "end-to-end")
drops = sum(v for k, v in r["drops"].items() if k != "observer")
print(f'{sys.argv[2]:<5} {sys.argv[3]:<5} {e2e["p50_ms"]:8.3f}ms {e2e["p99_ms"]:8.3f}ms {drops:6d}  {sys.argv[4] or "-"}')
PY
    rm -f "$OUT"/*.mcap
  done
done
