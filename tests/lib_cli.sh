# lib_cli.sh: what the end-to-end tool tests (tests/cli*.sh) share: the
# binary under test ($1), a temporary folder removed on exit, pass/fail
# counters, and the checks. Sourced, not run.
set -u
crease=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
passed=0
failed=0
# Set by ctest in the quick builds (clang, sanitizers: CMakeLists.txt, tests/test.h): the
# heaviest scripts train and simulate less there and leave the checks that need the full
# size to the release stage.
quick=${CREASE_TEST_QUICK:-0}
size() { if [[ $quick != 0 ]]; then echo "$2"; else echo "$1"; fi; } # size FULL SMALL

check() { # check NAME COMMAND... : the command must succeed
  local name=$1; shift
  if "$@" >/dev/null; then passed=$((passed + 1)); else failed=$((failed + 1)); echo "FAIL: $name" >&2; fi
}

# expect_exit CODE PATTERN ARGS...: crease ARGS exits with CODE and stderr matches PATTERN
expect_exit() {
  local code=$1 pattern=$2; shift 2
  "$crease" "$@" >"$tmp/stdout" 2>"$tmp/stderr"
  local got=$?
  if [[ $got -eq $code ]] && grep -Eq -- "$pattern" "$tmp/stderr"; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    echo "FAIL: crease $* -> exit $got (want $code), stderr: $(head -c 300 "$tmp/stderr")" >&2
  fi
}

json_has() { # json_has FILE KEY...: the last stdout line is one JSON object with these keys
  local line; line=$(tail -n 1 "$1")
  [[ $line == \{*\} ]] || return 1
  shift
  for k in "$@"; do grep -q "\"$k\":" <<<"$line" || return 1; done
}

# json_below FILE KEY LIMIT: the number at KEY in FILE's last line is below LIMIT
json_below() {
  local v; v=$(tail -n 1 "$1" | grep -o "\"$2\":[-0-9.eE+]*" | head -n 1 | cut -d: -f2)
  [[ -n $v ]] && awk -v v="$v" -v l="$3" 'BEGIN { exit !(v < l) }'
}

# st_meta_sub IN OUT KEY REGEX REPL: copy safetensors IN to OUT with Python's
# re.sub(REGEX, REPL) applied to the string at __metadata__[KEY] (an edited checkpoint)
st_meta_sub() {
  python3 - "$@" <<'PY'
import json, re, struct, sys
src, dst, key, pat, rep = sys.argv[1:6]
b = open(src, 'rb').read()
n = struct.unpack('<Q', b[:8])[0]
h = json.loads(b[8:8 + n])
h['__metadata__'][key] = re.sub(pat, rep, h['__metadata__'][key])
s = json.dumps(h, separators=(',', ':')).encode()
s += b' ' * (-(8 + len(s)) % 8)
open(dst, 'wb').write(struct.pack('<Q', len(s)) + s + b[8 + n:])
PY
}

# epochs_are FILE N: FILE's lines are epochs 1..N, one each, in order
epochs_are() {
  [[ $(grep -o '"epoch":[0-9]*' "$1" | cut -d: -f2 | tr '\n' ' ') == "$(seq -s ' ' 1 "$2") " ]]
}
