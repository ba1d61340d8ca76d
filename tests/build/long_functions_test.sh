#!/usr/bin/env bash
# The size rule of issue 33 in every folder: scripts/long_functions lists no
# function over 120 lines and no main() over 100. Skipped, saying so, where
# Universal Ctags (which finds where a function ends) is not installed.
#   long_functions_test.sh SOURCE_DIR
set -uo pipefail
version=$(ctags --version 2>/dev/null || true)
if [[ "$version" != *"Universal Ctags"* ]]; then
  echo "SKIP: needs Universal Ctags (apt-get install universal-ctags)"
  exit 77
fi
out=$("$1/scripts/long_functions")
status=$?
echo "$out"
if ((status != 0)); then
  echo "FAIL: split the functions listed above (docs/development.md, \"Style\")"
  exit 1
fi
