#!/usr/bin/env bash
# Run every fuzz target for N seconds each, on a corpus seeded from fuzz/corpus/<name>.
# Usage: fuzz.sh BUILD_DIR SECONDS
set -euo pipefail
build=$1
seconds=$2
root=$(cd "$(dirname "$0")/.." && pwd)
total=0
for bin in "$build"/fuzz_*; do
  [[ -x "$bin" ]] || continue
  name=$(basename "$bin")
  corpus="$build/corpus/$name"
  mkdir -p "$corpus"
  [[ -d "$root/fuzz/corpus/$name" ]] && cp -n "$root/fuzz/corpus/$name"/* "$corpus"/ 2>/dev/null || true
  log="$build/$name.log"
  if ! "$bin" -max_total_time="$seconds" -max_len=65536 -rss_limit_mb=2048 \
        -artifact_prefix="$build/$name-" "$corpus" >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "fuzz: $name found a crash (log: $log)" >&2
    exit 1
  fi
  runs=$(grep -Eo 'Done [0-9]+ runs' "$log" | grep -Eo '[0-9]+' | tail -n 1)
  echo "fuzz: $name: ${runs:-?} executions in ${seconds}s, no crash"
  total=$((total + ${runs:-0}))
done
echo "fuzz: $total executions in all"
