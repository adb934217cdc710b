#!/usr/bin/env bash
# bench_view.sh: frames per second of a `crease view` page in headless Chromium: a
# 150-frame garment of 10,000 vertices (a 100 x 100 cloth waving above the head) with
# the mannequin walking under it (pose-body, 150 frames). The page's #bench=S mode
# draws a new frame on every animation frame for S seconds and logs what it reached;
# the sequence plays at its own rate (30 fps) when that is at least 30.
# Software GL (SwiftShader) on the CPU: a desktop GPU is faster.
# Usage: [BENCH_SIZE=W,H] [BENCH_HASH=&aa=1] bench_view.sh PATH_TO_CREASE PATH_TO_VIEW_CHECK [SECONDS]
set -euo pipefail
crease=$1 vc=$2 seconds=${3:-5}
command -v chromium >/dev/null || { echo "bench_view: chromium is not installed" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$crease" primitive plane --res 100 -o "$tmp/cloth.obj" >/dev/null
"$vc" wave "$tmp/cloth.pc2" 100 150
"$crease" pose-body --clip walk --frames 150 -o "$tmp/body.glb" >/dev/null 2>&1
"$crease" view "$tmp/cloth.pc2@$tmp/cloth.obj+$tmp/body.glb" -o "$tmp/page" --json 2>/dev/null
timeout $((seconds + 60)) chromium --headless --no-sandbox --use-gl=angle --use-angle=swiftshader \
  --enable-unsafe-swiftshader --disable-dev-shm-usage --no-first-run --disable-extensions \
  --user-data-dir="$tmp/profile" --enable-logging=stderr --v=0 --window-size=${BENCH_SIZE:-1280,720} \
  --remote-debugging-port=0 "file://$tmp/page/index.html#bench=$seconds${BENCH_HASH:-}" 2>"$tmp/log" &
pid=$!
for _ in $(seq $((10 * (seconds + 50)))); do
  grep -q 'crease-view: bench' "$tmp/log" && break
  grep -q 'crease-view: error' "$tmp/log" && break
  sleep 0.1
done
kill $pid 2>/dev/null || true
wait $pid 2>/dev/null || true
grep -o '"crease-view: [^"]*"' "$tmp/log"
grep -q 'crease-view: bench' "$tmp/log"
