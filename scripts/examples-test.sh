#!/usr/bin/env bash
# Checks the installed CMake package: installs a built tree into a temporary prefix
# (cmake --install), configures and builds examples/minimal and examples/stages against it
# (find_package(endocast) with CMAKE_PREFIX_PATH=<prefix>), and runs them, the installed CLI and
# the installed 3D Slicer wrapper on a small phantom. Registered as the ctest test
# ExamplesInstalledPackage (label "examples"); the temporary prefix is removed on exit.
# Usage: bash scripts/examples-test.sh [BUILD_DIR, default build]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${1:-build}"
CMAKE="${CMAKE:-cmake}"
if [ ! -f "$BUILD/CMakeCache.txt" ]; then
  echo "examples-test: $BUILD is not a configured build tree (run scripts/build.sh first)" >&2
  exit 2
fi
TMP=$(mktemp -d "${TMPDIR:-/tmp}/endocast-examples.XXXXXX")
trap 'rm -rf "$TMP"' EXIT
PREFIX="$TMP/prefix"

echo "examples-test: installing $BUILD into $PREFIX"
"$CMAKE" --install "$BUILD" --prefix "$PREFIX" >"$TMP/install.log" || { cat "$TMP/install.log"; exit 1; }

for ex in minimal stages; do
  echo "examples-test: building examples/$ex against the installed package"
  "$CMAKE" -S "examples/$ex" -B "$TMP/build-$ex" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_PREFIX_PATH="$PREFIX" >"$TMP/configure-$ex.log" || { cat "$TMP/configure-$ex.log"; exit 1; }
  "$CMAKE" --build "$TMP/build-$ex" >"$TMP/build-$ex.log" || { cat "$TMP/build-$ex.log"; exit 1; }
done

expect() {  # expect PATTERN FILE: fail unless FILE has a line matching PATTERN
  if ! grep -q -- "$1" "$2"; then
    echo "examples-test: expected '$1' in the output:" >&2
    cat "$2" >&2
    exit 1
  fi
}

echo "examples-test: running on a 2 mm phantom"
"$PREFIX/bin/endocast" phantom "$TMP/phantom.nrrd" --preset human --spacing 2 2 2 -q
"$TMP/build-minimal/endocast_minimal" | tee "$TMP/minimal-phantom.txt"
expect '^true ECV ' "$TMP/minimal-phantom.txt"
"$TMP/build-minimal/endocast_minimal" "$TMP/phantom.nrrd" | tee "$TMP/minimal-file.txt"
expect '^ECV [0-9.]* mL' "$TMP/minimal-file.txt"
"$TMP/build-stages/endocast_stages" "$TMP/phantom.nrrd" 2>&1 | tee "$TMP/stages.txt"
for stage in read binarize fill distance seeds watershed openings polygonize measure; do
  expect "^$stage " "$TMP/stages.txt"
done
expect 'closed 2-manifold yes' "$TMP/stages.txt"

# DICOM: the installed CLI loads the installed GDCM module (lib/endocast/libendocast_gdcm.so); a
# program built against the package links GDCM's part instead (endocast::endocast_gdcm).
DICOM="../shared/data/headphantom-dicom"
if [ -d "$DICOM" ]; then
  echo "examples-test: DICOM through the installed CLI (its GDCM module) and the package (linked)"
  "$PREFIX/bin/endocast" series "$DICOM" >"$TMP/series.txt" 2>&1 || { cat "$TMP/series.txt"; exit 1; }
  expect '1 DICOM series in 209 files' "$TMP/series.txt"
  "$TMP/build-minimal/endocast_minimal" "$DICOM" 250 | tee "$TMP/minimal-dicom.txt"
  expect '^ECV [0-9.]* mL' "$TMP/minimal-dicom.txt"
else
  echo "examples-test: SKIPPED the DICOM checks: $DICOM is absent"
fi

echo "examples-test: the installed Slicer wrapper describes extract"
"$PREFIX/share/endocast/slicer/endocast-extract" --xml >"$TMP/slicer.xml"
expect '<title>Endocast extraction</title>' "$TMP/slicer.xml"
echo "examples-test: ok"
