#!/usr/bin/env bash
# Installs every build and test dependency of endocast from Debian packages.
# Idempotent: packages already present are skipped by apt; runs apt-get update only when needed.
set -euo pipefail

PKGS=(
  build-essential cmake ninja-build pkg-config
  zlib1g-dev libpng-dev libdeflate-dev libtiff-dev
  libinsighttoolkit5-dev libgdcm-tools libgdcm-dev
  libcgal-dev libgmp-dev libmpfr-dev
  libopenmesh-dev
  libeigen3-dev
  libopencv-dev
  libcli11-dev nlohmann-json3-dev
  libtbb-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  clang libclang-rt-14-dev
  snakemake
  python3 python3-dev pybind11-dev python3-pybind11 python3-numpy python3-pytest  # the Python module
  python3-matplotlib  # examples/python's plot
  nodejs       # npm (below): three.js for the --html report, embedded at build time
  chromium     # headless browser for the HTML report's test (skipped when absent)
)

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

missing=()
for p in "${PKGS[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ "${#missing[@]}" -eq 0 ]; then
  echo "install-deps: all ${#PKGS[@]} packages already installed"
else
  echo "install-deps: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# three.js from the npm registry, at the version pinned in apps/html/package-lock.json; CMake
# embeds it into the binary. Skipped when already installed at that version.
# Debian's nodejs comes without npm (a separate package); NodeSource's nodejs includes it.
if ! command -v npm >/dev/null; then
  $SUDO apt-get install -y -q --no-install-recommends npm || echo "install-deps: could not install npm" >&2
fi
html="$(cd "$(dirname "$0")/.." && pwd)/apps/html"
want="$(sed -n 's/^ *"three": "\([0-9.]*\)".*/\1/p' "$html/package.json" | head -n1)"
have="$(sed -n 's/^ *"version": "\([0-9.]*\)".*/\1/p' "$html/node_modules/three/package.json" 2>/dev/null | head -n1 || true)"
if [ "$have" = "$want" ]; then
  echo "install-deps: three.js $have already in apps/html/node_modules"
elif command -v npm >/dev/null; then
  echo "install-deps: npm ci in apps/html (three.js $want)"
  (cd "$html" && npm ci --no-audit --no-fund)
else
  echo "install-deps: npm not found; endocast extract --html will have no 3D view" >&2
fi
