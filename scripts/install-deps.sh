#!/usr/bin/env bash
# Installs Fascicle's build and test dependencies from Debian 12 packages.
# Idempotent: does nothing when every package is already installed.
# Uses sudo when not root.
set -euo pipefail

packages=(
  build-essential cmake make pkg-config ccache
  libcgal-dev libgmp-dev libmpfr-dev
  libeigen3-dev libboost-dev libtbb-dev
  libglew-dev libegl-dev libgl-dev libopengl-dev libegl-mesa0 libgl1-mesa-dri
  libpng-dev
  catch2 libcli11-dev nlohmann-json3-dev libspdlog-dev libfmt-dev
  python3 python3-numpy python3-vtk9 python3-meshio
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
