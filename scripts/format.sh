#!/usr/bin/env bash
# Formats every tracked C/C++ file with .clang-format (clang-format-14), or checks it.
#
#   scripts/format.sh           # rewrite the files in place
#   scripts/format.sh --check   # change nothing; list the files that differ, exit 1 if any
#                               # (the ctest `format_check`)
# CLANG_FORMAT=clang-format-15 scripts/format.sh  picks another binary (the output may differ).
set -euo pipefail
cd "$(dirname "$0")/.."
clang_format=${CLANG_FORMAT:-clang-format-14}
if ! command -v "$clang_format" >/dev/null 2>&1; then
  echo "format: $clang_format not found: apt-get install clang-format-14 (scripts/setup.sh installs it)" >&2
  exit 77  # ctest shows format_check as skipped, not passed
fi
mode=fix
case "${1:-}" in
  --check) mode=check ;;
  "") ;;
  *) echo "usage: scripts/format.sh [--check]" >&2; exit 2 ;;
esac

if ! git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  echo "format: not a git checkout: the file list comes from git ls-files" >&2
  exit 77
fi
mapfile -t files < <(git ls-files -- '*.c' '*.cc' '*.cpp' '*.cxx' '*.h' '*.hh' '*.hpp')
if [[ $mode == fix ]]; then
  printf '%s\0' "${files[@]}" | xargs -0 -n 32 -P "$(nproc)" "$clang_format" -i --style=file
  echo "format: formatted ${#files[@]} files"
  exit 0
fi
# --dry-run --Werror exits non-zero for a file that would change; name each such file.
bad=()
for f in "${files[@]}"; do
  "$clang_format" --dry-run --Werror --style=file "$f" >/dev/null 2>&1 || bad+=("$f")
done
if ((${#bad[@]})); then
  echo "format: ${#bad[@]} of ${#files[@]} files differ from .clang-format (run scripts/format.sh):" >&2
  printf '  %s\n' "${bad[@]}" >&2
  exit 1
fi
echo "format: all ${#files[@]} files match .clang-format"
