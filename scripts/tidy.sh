#!/usr/bin/env bash
# Runs clang-tidy-14 with .clang-tidy (identifier naming, STYLE.md 9) over the
# production sources (core, tims, client, components, tools) that build/ compiles,
# using build/compile_commands.json. The ctest `tidy_naming`.
#
#   scripts/tidy.sh                     # every production source, -j$(nproc)
#   scripts/tidy.sh core/src/executor.cpp ...   # these files only
#   RACK_BUILD_DIR=out TIDY_JOBS=1 scripts/tidy.sh
# Headers are checked through the sources that include them (HeaderFilterRegex),
# each finding reported once. Exits 1 when there are findings.
set -euo pipefail
cd "$(dirname "$0")/.."
clang_tidy=${CLANG_TIDY:-clang-tidy-14}
build=${RACK_BUILD_DIR:-build}
jobs=${TIDY_JOBS:-$(nproc)}
if ! command -v "$clang_tidy" >/dev/null 2>&1; then
  echo "tidy: $clang_tidy not found: apt-get install clang-tidy-14 (scripts/setup.sh installs it)" >&2
  exit 77  # ctest shows tidy_naming as skipped, not passed
fi
if [[ ! -f $build/compile_commands.json ]]; then
  echo "tidy: $build/compile_commands.json missing: configure with cmake first (CMAKE_EXPORT_COMPILE_COMMANDS is on)" >&2
  exit 2
fi

if (($#)); then
  files=("$@")
elif ! git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  echo "tidy: not a git checkout: the file list comes from git ls-files (name the files instead)" >&2
  exit 77
else
  # Tracked production sources that the build compiles (optional components that
  # were not configured, e.g. without OpenCV, have no compile command).
  mapfile -t files < <(
    python3 - "$build/compile_commands.json" <<'PY'
import json, os, subprocess, sys
compiled = {os.path.realpath(e["file"]) for e in json.load(open(sys.argv[1]))}
tracked = subprocess.run(["git", "ls-files", "--", "core", "tims", "client", "components", "tools"],
                         capture_output=True, text=True, check=True).stdout.split()
for f in tracked:
    if f.endswith((".cpp", ".cc", ".c")) and os.path.realpath(f) in compiled:
        print(f)
PY
  )
fi
if ((${#files[@]} == 0)); then
  echo "tidy: no sources to check" >&2
  exit 2
fi

out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
started=$SECONDS
# One clang-tidy per source; the findings of each go to its own file.
printf '%s\n' "${files[@]}" | nl -ba -w1 -s' ' |
  xargs -P "$jobs" -L 1 sh -c '"$0" -p "$1" --quiet "$4" >"$2/$3.log" 2>&1 || true' \
    "$clang_tidy" "$build" "$out" 2>/dev/null ||
  true
# A header's finding shows once per source that includes it: report each once. A
# compile error is a finding too (clang-diagnostic-error), but for one that is clang 14's
# and not the code's: C++20 lets a lambda capture a structured binding (P1091R3, P1381R1;
# GCC 10, clang 16), clang 14 refuses it (tools/gui/backend.cpp, tools/rackctl/main.cpp).
# The naming check still runs over those files.
findings=$(cat "$out"/*.log | grep -E '^[^ ]+:[0-9]+:[0-9]+: (warning|error):' |
  grep -vE "reference to local binding '[^']+' declared in enclosing function|'[^']+' in capture list does not name a variable" |
  sort -u || true)
# Errors without a place (a missing compile command, a crash of clang-tidy).
unplaced=$(cat "$out"/*.log | grep -E '^error' || true)
count=0
[[ -n $findings ]] && count=$(printf '%s\n' "$findings" | wc -l)
if ((count)); then
  printf '%s\n' "$findings" | sed 's/,-warnings-as-errors//'
fi
echo "tidy: ${#files[@]} sources in $((SECONDS - started)) s with -j$jobs: $count finding(s)"
if [[ -n $unplaced ]]; then
  printf '%s\n' "$unplaced" | sort -u | sed 's/^/tidy: /' >&2
  exit 2
fi
((count == 0))
