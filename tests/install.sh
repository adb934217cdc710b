#!/usr/bin/env bash
# install.sh: the installed tree stands on its own. Installs BUILD_DIR into a
# temporary prefix (as `make install` does), then: every installed public
# header compiles alone, and twice in one file (include guards), with warnings
# as errors, in C and in C++ (extern "C"), and a C++ program using them links; examples/hello_mesh.c and a user of the simulator (CHOLMOD) build
# with nothing but the flags of the installed crease.pc and run; the installed
# tool answers --version.
#
# Usage: install.sh BUILD_DIR CC [EXTRA_CFLAGS]
#   EXTRA_CFLAGS: what every object linked with this build needs (the
#   sanitizer flags of an ASan build), passed to the compiler as words.
set -euo pipefail
build=${1:?usage: install.sh BUILD_DIR CC [EXTRA_CFLAGS]}
cc=${2:?usage: install.sh BUILD_DIR CC [EXTRA_CFLAGS]}
read -r -a extra <<<"${3:-}"
src=$(cd "$(dirname "$0")/.." && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "install: $*" >&2; exit 1; }

prefix=$tmp/prefix
cmake --install "$build" --prefix "$prefix" >"$tmp/install.log" || {
  cat "$tmp/install.log" >&2
  fail "cmake --install $build failed"
}
pc=$(find "$prefix" -name crease.pc -path '*/pkgconfig/*' | head -n 1)
[[ -n $pc ]] || fail "no pkgconfig/crease.pc under $prefix"
[[ -x $prefix/bin/crease ]] || fail "no bin/crease under $prefix"
[[ -n $(find "$prefix" -name libcrease.a) ]] || fail "no libcrease.a under $prefix"

# Every header of include/crease installed, each compiling alone.
n=0
for h in "$src"/include/crease/*.h; do
  name=$(basename "$h")
  [[ -f $prefix/include/crease/$name ]] || fail "crease/$name is not installed"
  printf '#include <crease/%s>\n#include <crease/%s>\n' "$name" "$name" >"$tmp/one.c"
  "$cc" -std=c11 -Wall -Wextra -Werror -fsyntax-only -I"$prefix/include" "$tmp/one.c" \
    2>"$tmp/cc.log" || { cat "$tmp/cc.log" >&2; fail "crease/$name does not compile alone"; }
  n=$((n + 1))
done

# The same headers from C++ (each wraps its declarations in extern "C"), with the C++
# compiler of the C compiler's family, and a C++ program linked through crease.pc below.
case $(basename "$cc") in
  clang*) cxx=$(dirname "$cc")/$(basename "$cc" | sed 's/^clang/clang++/') ;;
  gcc*) cxx=$(dirname "$cc")/$(basename "$cc" | sed 's/^gcc/g++/') ;;
  *) cxx=$(dirname "$cc")/c++ ;;
esac
[[ -x $cxx ]] || cxx=$(command -v "$(basename "$cxx")" || true)
[[ -n $cxx ]] || fail "no C++ compiler beside $cc (build-essential's g++, clang's clang++)"
for h in "$src"/include/crease/*.h; do
  name=$(basename "$h")
  printf '#include <crease/%s>\n#include <crease/%s>\n' "$name" "$name" >"$tmp/one.cpp"
  "$cxx" -std=c++11 -Wall -Wextra -Werror -fsyntax-only -I"$prefix/include" "$tmp/one.cpp" 2>"$tmp/cc.log" || { cat "$tmp/cc.log" >&2; fail "crease/$name does not compile as C++"; }
done

# A user's program through pkg-config only: the prefix comes from where crease.pc lies.
export PKG_CONFIG_PATH=$(dirname "$pc")
read -r -a flags <<<"$(pkg-config --cflags --libs crease)" || fail "pkg-config --cflags --libs crease failed"
"$cc" -std=c11 "${extra[@]}" -o "$tmp/hello_mesh" "$src/examples/hello_mesh.c" "${flags[@]}" \
  2>"$tmp/cc.log" || { cat "$tmp/cc.log" >&2; fail "hello_mesh.c does not link with: ${flags[*]}"; }
(cd "$tmp" && ./hello_mesh "$tmp/hello.png" >"$tmp/hello.out") || fail "hello_mesh failed"
[[ $(head -c 4 "$tmp/hello.png" | tail -c 3) == PNG ]] || fail "hello_mesh wrote no PNG"
# The simulator's object pulls in CHOLMOD, which hello_mesh does not need.
cat >"$tmp/sim_def.c" <<'EOF_C'
#include <crease/phys_sim.h>
int main(void) { return cr_sim_default_def().dt > 0 ? 0 : 1; }
EOF_C
"$cc" -std=c11 "${extra[@]}" -o "$tmp/sim_def" "$tmp/sim_def.c" "${flags[@]}" 2>"$tmp/cc.log" ||
  { cat "$tmp/cc.log" >&2; fail "a cr_sim user does not link with: ${flags[*]}"; }
"$tmp/sim_def" || fail "cr_sim_default_def().dt is not positive"
# A C++ program: every header in one file, a model made and written out as JSON, linked as C++.
cat >"$tmp/user.cpp" <<'EOF_CXX'
#include <cstdio>
#include <cstdlib>
EOF_CXX
for h in "$src"/include/crease/*.h; do echo "#include <crease/$(basename "$h")>" >>"$tmp/user.cpp"; done
cat >>"$tmp/user.cpp" <<'EOF_CXX'
int main() {
    cr_error err = {};
    cr_swingar_def d = cr_swingar_default_def();
    if (cr_swingar_size_def("tiny", &d, &err) != CR_OK) return 1;
    cr_swingar *m = nullptr;
    if (cr_swingar_create(&d, 1, &m, &err) != CR_OK) return 2;
    char *json = cr_swingar_def_to_json(cr_swingar_get_def(m));
    int ok = json && std::printf("%s\n", json) > 0;
    std::free(json);
    cr_swingar_destroy(m);
    return ok ? 0 : 3;
}
EOF_CXX
"$cxx" -std=c++11 -Wall -Wextra -Werror "${extra[@]}" -o "$tmp/user_cxx" "$tmp/user.cpp" "${flags[@]}" \
  2>"$tmp/cc.log" || { cat "$tmp/cc.log" >&2; fail "a C++ program does not build with: ${flags[*]}"; }
"$tmp/user_cxx" >"$tmp/user_cxx.out" || fail "the C++ program failed"
grep -q '"motion_window"' "$tmp/user_cxx.out" || fail "the C++ program printed no def"
"$prefix/bin/crease" --version | grep -q '^crease ' || fail "the installed crease has no --version"
echo "install: $n headers compile alone in C and C++ ($cxx); a C++ program, hello_mesh and a cr_sim user link through crease.pc (${flags[*]}) and runs"
