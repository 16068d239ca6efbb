#!/usr/bin/env bash
# Clean build and test time of `cargo test --workspace` at each commit given, one after the other:
# a fresh clone, an empty target directory, no incremental compilation (as .ci/run builds).
# Usage: bench/clean_build_time.sh COMMIT... (about 25 minutes per commit on 2 cores; keep the
# machine otherwise idle). Prints one line per phase.
set -u
repo=$(cd "$(dirname "$0")/.." && pwd)
export CARGO_INCREMENTAL=0 CARGO_TERM_COLOR=never
for commit in "$@"; do
  work=$(mktemp -d)
  git clone -q "$repo" "$work/src" && git -C "$work/src" checkout -q "$commit" || exit 1
  export CARGO_TARGET_DIR="$work/target"
  cd "$work/src" || exit 1
  start=$(date +%s); cargo test --workspace --locked --no-run > "$work/build.log" 2>&1; rc=$?
  echo "$commit clean build rc=$rc $(( $(date +%s) - start )) s"
  start=$(date +%s); cargo test --workspace --locked > "$work/test.log" 2>&1; rc=$?
  echo "$commit test run rc=$rc $(( $(date +%s) - start )) s"
  echo "$commit target $(du -sh "$CARGO_TARGET_DIR" | cut -f1)"
  cd / && rm -rf "$work"
done
