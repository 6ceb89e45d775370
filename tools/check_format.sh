#!/usr/bin/env bash
# Fails (listing the files) when a C++ source is not formatted per .clang-format.
# Fix with: git ls-files '*.cpp' '*.hpp' '*.h' | grep -v third_party_stubs | xargs clang-format -i
set -euo pipefail
cd "$(dirname "$0")/.."
bad=()
while IFS= read -r f; do
  clang-format --dry-run --Werror "$f" >/dev/null 2>&1 || bad+=("$f")
done < <(git ls-files '*.cpp' '*.hpp' '*.h' | grep -v '^third_party_stubs/')
if [ ${#bad[@]} -gt 0 ]; then
  echo "check_format.sh: not formatted per .clang-format: ${bad[*]}" >&2
  exit 1
fi
echo "check_format.sh: all C++ sources formatted"
