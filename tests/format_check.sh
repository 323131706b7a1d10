#!/bin/sh
# Every C++ source of the repository follows .clang-format: prints the first differences and fails
# otherwise. Usage: tests/format_check.sh CLANG_FORMAT SOURCE_DIR. Fix with
#   clang-format -i $(git ls-files '*.cpp' '*.hpp')
set -eu
clang_format=$1
cd "$2"
files=$(find src tests bench fuzz -path fuzz/corpus -prune -o \( -name '*.cpp' -o -name '*.hpp' \) -print | sort)
if ! "$clang_format" --dry-run --Werror --style=file $files 2>/tmp/flatland-format.$$; then
  head -n 40 /tmp/flatland-format.$$
  echo "format check: the files above do not follow .clang-format; run: clang-format -i FILE..."
  rm -f /tmp/flatland-format.$$
  exit 1
fi
rm -f /tmp/flatland-format.$$
echo "format check: $(echo "$files" | wc -l) files follow .clang-format"
