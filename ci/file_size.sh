#!/usr/bin/env bash
# Fails when a non-test Rust source file reaches 800 lines (CODE_STYLE.md): a file that long
# holds more than one job. Counted: the lines before a file's unit-test module (`#[cfg(test)]`
# followed by `mod ...`); not counted: integration tests (`tests/`) and test-only modules
# (`tests.rs`).
set -euo pipefail
cd "$(dirname "$0")/.."
limit=800
status=0
while IFS= read -r file; do
  lines=$(awk '
    /^#\[cfg\(test\)\]/ { pending = NR; next }
    pending && /^(pub(\([a-z]+\))? )?mod / { exit }
    { if (pending) { pending = 0 } }
    { count = NR }
    END { print count + 0 }
  ' "$file")
  if [ "$lines" -ge "$limit" ]; then
    echo "$file: $lines non-test lines (the limit is $((limit - 1)))" >&2
    status=1
  fi
done < <(git ls-files '*.rs' | grep -v '^tests/' | grep -v '/tests\.rs$')
if [ "$status" -eq 0 ]; then
  echo "every non-test source file is under $limit lines"
fi
exit "$status"
