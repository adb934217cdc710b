#!/usr/bin/env bash
# Run every fuzz target for N seconds each, on a corpus seeded from fuzz/corpus/<name>,
# as many at once as there are cores (FUZZ_JOBS to choose; each target is one process).
# Usage: fuzz.sh BUILD_DIR SECONDS
set -euo pipefail
build=$1
seconds=$2
jobs=${FUZZ_JOBS:-$(nproc)}
root=$(cd "$(dirname "$0")/.." && pwd)

fuzz_one() { # fuzz_one BIN: exit 1 with the log's tail on a crash
  local bin=$1 name corpus log
  name=$(basename "$bin")
  corpus="$build/corpus/$name"
  mkdir -p "$corpus"
  [[ -d "$root/fuzz/corpus/$name" ]] && cp -n "$root/fuzz/corpus/$name"/* "$corpus"/ 2>/dev/null || true
  log="$build/$name.log"
  if ! "$bin" -max_total_time="$seconds" -max_len=65536 -rss_limit_mb=2048 \
        -artifact_prefix="$build/$name-" "$corpus" >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "fuzz: $name found a crash (log: $log)" >&2
    return 1
  fi
}

bins=()
for bin in "$build"/fuzz_*; do [[ -x "$bin" && -f "$bin" ]] && bins+=("$bin"); done
failed=0
running=0
for bin in "${bins[@]}"; do
  if (( running >= jobs )); then wait -n || failed=1; running=$((running - 1)); fi
  fuzz_one "$bin" &
  running=$((running + 1))
done
while (( running > 0 )); do wait -n || failed=1; running=$((running - 1)); done
(( failed == 0 )) || exit 1

total=0
for bin in "${bins[@]}"; do
  name=$(basename "$bin")
  runs=$(grep -Eo 'Done [0-9]+ runs' "$build/$name.log" | grep -Eo '[0-9]+' | tail -n 1 || true)
  echo "fuzz: $name: ${runs:-?} executions in ${seconds}s, no crash"
  total=$((total + ${runs:-0}))
done
echo "fuzz: $total executions in all"
