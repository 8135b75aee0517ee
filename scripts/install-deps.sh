#!/usr/bin/env bash
# Installs every package the project needs from Debian's archive.
# Idempotent: when everything is already installed it does nothing (and
# does not touch the network). Uses sudo when not run as root.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config make
  liblcm-dev liblcm-bin liblcm-java
  libopencv-dev libjpeg-dev   # libjpeg: MJPEG frames decoded with their damage said
  libzbar-dev zbar-tools
  libv4l-dev
  libegl-dev libgles-dev libegl-mesa0 libgl1-mesa-dri libgbm-dev
  libgtest-dev libgmock-dev
  default-jdk-headless libjchart2d-java
  libqrencode-dev nlohmann-json3-dev libcli11-dev libyaml-cpp-dev
  zlib1g-dev fonts-dejavu-core   # ld-generate's PNG: its pHYs chunk's CRC, its labels' font
  libapriltag-dev
  iproute2 jq
  clang libclang-rt-14-dev   # libFuzzer targets (tests/fuzz)
)

missing=()
for p in "${PACKAGES[@]}"; do
  # (read whole, then matched: a pipe into grep -q can fail under pipefail)
  if [[ "$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null)" != *"install ok installed"* ]]; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
