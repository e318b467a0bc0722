#!/usr/bin/env bash
# Installs every Debian 12 package nirslam needs to build, test and run. Idempotent and
# non-interactive; uses sudo when not run as root.
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config git python3
  # the ThreadSanitizer stage of tests/run_all.sh compiles with clang (its runtime is a package of its own)
  clang-14 libclang-rt-14-dev
  # core
  libeigen3-dev libopencv-dev libceres-dev libv4l-dev libyaml-cpp-dev nlohmann-json3-dev
  libspdlog-dev libcli11-dev libzip-dev libpng-dev libjpeg-dev
  # ui and front ends
  libimgui-dev libstb-dev libfreetype-dev libglfw3-dev libegl-dev libgl-dev libegl-mesa0
  libgl1-mesa-dri
  # tests, benchmarks, headless screenshots under a real X server
  libgtest-dev libgmock-dev libbenchmark-dev xvfb xauth imagemagick
  # session reports opened in a real browser (headless); the Debian package and its man page
  chromium help2man dpkg-dev fakeroot man-db
  # real camera data used by tests (ViSP cube sequence, OpenCV sample pairs)
  visp-images-data opencv-doc
)

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
if [ ${#missing[@]} -gt 0 ]; then
  echo "Installing: ${missing[*]}"
  "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
else
  echo "All ${#packages[@]} packages already installed."
fi
