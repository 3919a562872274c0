#!/usr/bin/env bash
# scripts/lib/check_tree.sh sanitized|fuzz BUILD [EXECUTABLE...]: proves that what is about to run is
# instrumented, before scripts/test --sanitize or scripts/fuzz trusts a silence: the tree was configured
# with HYDROJET_SANITIZE, each executable (default: all of BUILD/devel/lib/hydrojet_control) carries
# AddressSanitizer's runtime, and each of the package's libraries it loads, with the environment it
# will run in, comes from BUILD (a devel space or LD_LIBRARY_PATH of another tree would load
# uninstrumented ones), and its devel space chains to no other workspace. fuzz: the fuzzed libraries also carry libFuzzer's coverage instrumentation.
# Exit 1 with each offender named.
set -eo pipefail
mode=$1 build=$2
shift 2 || { echo "usage: check_tree.sh sanitized|fuzz BUILD [EXECUTABLE...]" >&2; exit 2; }
root=$(cd "$build" && pwd)
fail=0
complain() { echo "check_tree: $*" >&2; fail=1; }
grep -q '^HYDROJET_SANITIZE:BOOL=ON' "$root/CMakeCache.txt" 2>/dev/null || complain "$build is not configured with HYDROJET_SANITIZE=ON"
source "$(dirname "$0")/devel_parents.sh"
chained=$(devel_parents "$root/devel")
[ -z "$chained" ] || complain "$build/devel chains to other workspaces: $(echo $chained)"
exes=("$@")
[ ${#exes[@]} -gt 0 ] || mapfile -t exes < <(find "$root/devel/lib/hydrojet_control" -maxdepth 1 -type f -perm -u+x \
  -exec sh -c 'head -c4 "$1" | grep -q ELF' _ {} \; -print)
[ ${#exes[@]} -gt 0 ] || complain "no executables in $build"
for exe in "${exes[@]}"; do
  nm "$exe" 2>/dev/null | grep ' T __asan_init$' >/dev/null || complain "$exe is not built with AddressSanitizer"
  while read -r lib path; do
    case $path in
      "$root"/*) ;;
      *) complain "$(basename "$exe") loads $lib from ${path:-nowhere}, not from $build" ;;
    esac
  done < <(ldd "$exe" | awk '$1 ~ /^libhydrojet/ {print $1, $3}')
done
if [ "$mode" = fuzz ]; then
  for lib in hydrojet_config hydrojet_devices hydrojet_calibration; do
    nm -D "$root/devel/lib/lib$lib.so" 2>/dev/null | grep __sanitizer_cov >/dev/null || \
      complain "lib$lib.so has no coverage instrumentation (libFuzzer would fuzz blind)"
  done
fi
[ $fail -eq 0 ] && echo "check_tree: $build is instrumented ($mode; ${#exes[@]} executables, their libraries from $build)"
exit $fail
