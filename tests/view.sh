#!/usr/bin/env bash
# view.sh: `crease view` end to end. The tool: outputs, --json, usage and input errors.
# The page, in headless Chromium (skipped, exit 77, where chromium is absent): every
# panel loads, the page steps to frames 0, 6 and 12 (#frame=N) and is screenshot; the
# test fails on any console message that is not the page's own "crease-view:" status,
# on a blank panel, when the moving garment's panel at frame 0 equals frame 12, when
# --color-by changes nothing, and when the page served by --serve does not load.
# Usage: view.sh PATH_TO_CREASE PATH_TO_VIEW_CHECK
source "$(dirname "$0")/lib_cli.sh" "$1"
vc=$2

if [[ ! -s /usr/share/javascript/three/build/three.min.js ]]; then
  echo "view.sh: SKIP: three.js is not installed (Debian libjs-three; scripts/deps.sh installs it)" >&2
  exit 77
fi

# --- the tool --------------------------------------------------------------------------
"$crease" primitive plane --res 12 -o "$tmp/cloth.obj" >/dev/null
"$crease" primitive sphere -o "$tmp/sphere.obj" >/dev/null
for p in "" --plastic; do
  "$crease" simulate --garment "$tmp/cloth.obj" --garment-offset 0,0.35,0 --object sphere \
    --frames 12 $p -o "$tmp/sim$p" --quiet 2>/dev/null
done
check "view --help" bash -c "'$crease' view --help | grep -q usage"
check "view writes" bash -c "'$crease' view '$tmp/sim/sim.glb+$tmp/sphere.obj' \
  '$tmp/sim--plastic/sim.pc2@$tmp/cloth.obj' --label elastic --label plastic -o '$tmp/page' \
  --json > '$tmp/view.json' 2>/dev/null"
check "view fields" json_has "$tmp/view.json" command page panels frames fps data_bytes embedded
check "view 13 frames at 30 fps" grep -q '"frames":13,"fps":30,' "$tmp/view.json"
check "view embedded" grep -q '"embedded":true' "$tmp/view.json"
check "view three.js beside" test -s "$tmp/page/three.min.js" -a -s "$tmp/page/OrbitControls.js"
check "view no data/" test ! -e "$tmp/page/data"
check "view labels" grep -q '"label":"plastic"' "$tmp/page/index.html"
"$vc" npy "$tmp/err.npy" 13 144
check "view --color-by" bash -c "'$crease' view '$tmp/sim/sim.glb' --color-by '$tmp/err.npy' \
  -o '$tmp/color' 2>/dev/null && grep -q colorbar '$tmp/color/index.html'"
mkdir -p "$tmp/evaldir" && cp "$tmp/err.npy" "$tmp/evaldir/vertex_error.npy"
check "view --color-by DIR" bash -c "'$crease' view '$tmp/sim/sim.glb' --color-by '$tmp/evaldir' -o '$tmp/color2' 2>/dev/null"
check "view --embed-max 0" bash -c "'$crease' view '$tmp/sim/sim.glb+$tmp/sphere.obj' --embed-max 0 \
  -o '$tmp/big' --json 2>/dev/null | grep -q '\"embedded\":false' && test -s '$tmp/big/data/p0_1.bin'"
expect_exit 2 "missing -o" view "$tmp/sim/sim.glb"
expect_exit 2 "at least one sequence" view -o "$tmp/x"
expect_exit 2 "--label" view "$tmp/sim/sim.glb" --label a --label b -o "$tmp/x"
expect_exit 1 "nothere.glb" view "$tmp/nothere.glb" -o "$tmp/x"
cp "$tmp/sim/sim.pc2" "$tmp/alone.pc2"
expect_exit 1 "alone.pc2: a .pc2 needs its rest mesh" view "$tmp/alone.pc2" -o "$tmp/x"
expect_exit 1 "has 144 points but rest mesh .*sphere.obj" view "$tmp/sim/sim.pc2@$tmp/sphere.obj" -o "$tmp/x"
"$vc" npy "$tmp/bad.npy" 5 144
expect_exit 1 "bad.npy: expected shape \(13,144\) or \(144\), got \(5,144\)" \
  view "$tmp/sim/sim.glb" --color-by "$tmp/bad.npy" -o "$tmp/x"
expect_exit 1 "three.min.js: not found" view "$tmp/sim/sim.glb" --three "$tmp/none" -o "$tmp/x"
expect_exit 1 "no such page" view --serve "$tmp/none"

if (( failed > 0 )); then echo "view.sh: $passed passed, $failed failed" >&2; exit 1; fi
# The page's script is the same whatever compiled the tool: a full run checks it, a quick
# one (clang, sanitizers: CREASE_TEST_QUICK) stops at the tool.
if [[ $quick != 0 ]]; then echo "view.sh: $passed passed; the browser checks are left to a full run"; exit 0; fi
if ! command -v chromium >/dev/null; then
  echo "view.sh: $passed passed; SKIP the browser checks: chromium is not installed (scripts/deps.sh installs it)" >&2
  exit 77
fi

# --- the page in headless Chromium -----------------------------------------------------
W=960 H=540 BAR=44
# Software GL (no GPU here), no sandbox (CI runs as root), a profile of our own.
chrome=(chromium --headless --no-sandbox --use-gl=angle --use-angle=swiftshader
        --enable-unsafe-swiftshader --disable-dev-shm-usage --no-first-run --disable-extensions
        --hide-scrollbars --user-data-dir="$tmp/profile" --enable-logging=stderr --v=0
        --window-size=$W,$H)
shot() { # shot URL PNG [flags]: screenshot, console lines in PNG.log
  local url=$1 png=$2; shift 2
  timeout 60 "${chrome[@]}" "$@" --screenshot="$png" "$url" >/dev/null 2>"$png.log"
  grep -o 'CONSOLE[^"]*"[^"]*"' "$png.log" | sed 's/^[^"]*//' > "$png.console"
  test -s "$png"
}
console_clean() { # only the page's own status lines, none of them an error
  ! grep -v '^"crease-view: ' "$1.console" | grep -q . && ! grep -q 'crease-view: error' "$1.console"
}
# Boxes of the two panels (left, right), below their labels and above the bar.
left=(0 30 $((W / 2)) $((H - BAR)))
right=($((W / 2)) 30 $W $((H - BAR)))
nonblank() { awk -v v="$("$vc" stats "$@")" 'BEGIN { exit !(v > 0.01) }'; }
differs() { awk -v v="$("$vc" diff "$@")" 'BEGIN { exit !(v > 0.005) }'; }

page="file://$tmp/page/index.html"
for f in 0 6 12; do
  check "page frame $f: screenshot" shot "$page#frame=$f" "$tmp/f$f.png"
  check "page frame $f: every panel loaded" grep -q "crease-view: ready panels=2 frames=13 frame=$f\"" \
    "$tmp/f$f.png.console"
  check "page frame $f: no console error" console_clean "$tmp/f$f.png"
  check "page frame $f: left panel drawn" nonblank "$tmp/f$f.png" "${left[@]}"
  check "page frame $f: right panel drawn" nonblank "$tmp/f$f.png" "${right[@]}"
done
check "page: the garment moves (frame 0 vs 12)" differs "$tmp/f0.png" "$tmp/f12.png" "${left[@]}"
check "page: the plastic garment moves (frame 0 vs 6)" differs "$tmp/f0.png" "$tmp/f6.png" "${right[@]}"

check "color page: screenshot" shot "file://$tmp/color/index.html#frame=12" "$tmp/c12.png"
check "color page: no console error" console_clean "$tmp/c12.png"
"$crease" view "$tmp/sim/sim.glb" -o "$tmp/plain" 2>/dev/null
check "plain page: screenshot" shot "file://$tmp/plain/index.html#frame=12" "$tmp/p12.png"
check "color page: colours differ from plain" differs "$tmp/c12.png" "$tmp/p12.png" 0 30 $W $((H - BAR))

# The page with data/ beside it: from file:// it says to serve it; served, it loads.
check "data/ page from file://: screenshot" shot "file://$tmp/big/index.html#frame=3" "$tmp/b.png"
check "data/ page from file:// says --serve" grep -q 'crease-view: error: .*crease view --serve' \
  "$tmp/b.png.console"
"$crease" view --serve "$tmp/big" --port 0 2>"$tmp/serve.log" &
server=$!
for _ in $(seq 50); do grep -q 'http://127.0.0.1:[0-9]*/' "$tmp/serve.log" && break; sleep 0.1; done
url=$(grep -o 'http://127.0.0.1:[0-9]*/' "$tmp/serve.log" | head -n 1)
check "serve: prints its URL" test -n "$url"
if [[ -n $url ]] && command -v curl >/dev/null; then
  check "serve: index.html" bash -c "curl -sf '$url' | grep -q crease-meta"
  check "serve: data block" bash -c "[[ \$(curl -sf '${url}data/p0_0.bin' | wc -c) -eq \
    \$(stat -c %s '$tmp/big/data/p0_0.bin') ]]"
  check "serve: no escape" bash -c "[[ \$(curl -s -o /dev/null -w '%{http_code}' --path-as-is \
    '${url}../view.json') == 404 ]]"
  check "serve: POST refused" bash -c "[[ \$(curl -s -o /dev/null -w '%{http_code}' -X POST '$url') == 405 ]]"
fi
if [[ -n $url ]]; then
  check "served page: screenshot" shot "${url}index.html#frame=3" "$tmp/s.png" --virtual-time-budget=5000
  check "served page: loaded" grep -q 'crease-view: ready panels=1 frames=13 frame=3"' "$tmp/s.png.console"
  check "served page: no console error" console_clean "$tmp/s.png"
  check "served page: drawn" nonblank "$tmp/s.png" 0 30 $W $((H - BAR))
fi
kill -INT $server
wait $server
check "serve: Ctrl-C stops it with status 0" test $? -eq 0

echo "view.sh: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
