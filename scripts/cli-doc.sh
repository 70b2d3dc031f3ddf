#!/usr/bin/env bash
# docs/cli.md from the CLI's own --help: `bash scripts/cli-doc.sh BIN` rewrites it,
# `bash scripts/cli-doc.sh --check BIN` fails (exit 1, with the diff) when it is stale (ctest Docs.CliReference).
set -euo pipefail
cd "$(dirname "$0")/.."
check=0
if [ "${1:-}" = "--check" ]; then check=1; shift; fi
BIN=${1:-build/bin/endocast}
help() { "$BIN" "$@" --help | sed -E 's#^Usage: [^ ]*endocast#Usage: endocast#'; }
{
  echo "# Command-line reference"
  echo
  echo "Generated from \`endocast --help\` and each subcommand's \`--help\` by \`bash scripts/cli-doc.sh\`;"
  echo "a test (\`Docs.CliReference\`) fails when this page differs from the program's help."
  echo "Lengths are in mm, isovalues in the scan's units (HU for DICOM)."
  echo
  echo '```'
  help
  echo '```'
  for sub in extract batch robustness series phantom inspect simplify compare; do
    echo
    echo "## endocast $sub"
    echo
    echo '```'
    help "$sub"
    echo '```'
  done
} > "${TMPDIR:-/tmp}/cli.md.$$"
if [ $check = 1 ]; then
  if ! diff -u docs/cli.md "${TMPDIR:-/tmp}/cli.md.$$"; then
    rm -f "${TMPDIR:-/tmp}/cli.md.$$"
    echo "docs/cli.md is stale: run bash scripts/cli-doc.sh $BIN" >&2
    exit 1
  fi
  rm -f "${TMPDIR:-/tmp}/cli.md.$$"
else
  mv "${TMPDIR:-/tmp}/cli.md.$$" docs/cli.md
fi
