#!/usr/bin/env bash
# Installs every build and test dependency of endocast from Debian packages.
# Idempotent: packages already present are skipped by apt; runs apt-get update only when needed.
set -euo pipefail

PKGS=(
  build-essential cmake ninja-build pkg-config
  zlib1g-dev
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
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
