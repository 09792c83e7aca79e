#!/usr/bin/env bash
# End-to-end checks of the `retrace` command line: exit codes and one-line error messages.
# Usage: cli_test.sh RETRACE_BINARY SHARED_DATA_DIR
set -u
bin=$1
data=${2:-}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
passed=0

# expect NAME EXPECTED_EXIT PATTERN -- COMMAND...: runs COMMAND, checks its exit code and that its combined output
# matches the extended regex PATTERN.
expect() {
  local name=$1 want=$2 pattern=$3
  shift 4
  local out rc
  out=$("$@" 2>&1)
  rc=$?
  if [[ $rc -ne $want ]] || ! grep -Eq -- "$pattern" <<<"$out"; then
    echo "FAIL $name: exit $rc (want $want), output:"
    echo "$out" | head -20
    failures=$((failures + 1))
  else
    passed=$((passed + 1))
  fi
}

expect version 0 '^retrace [0-9]+\.[0-9]+\.[0-9]+' -- "$bin" version
expect help 0 'Subcommands' -- "$bin" --help
expect unknown-subcommand 2 "unknown command 'xyz'" -- "$bin" xyz

# Further command checks are appended by each command (see the sections below).
for f in "$(dirname "$0")"/cli_test.d/*.sh; do
  [[ -e $f ]] || continue
  # shellcheck source=/dev/null
  source "$f"
done

echo "$passed passed, $failures failed"
[[ $failures -eq 0 ]]
