#!/usr/bin/env bash
# Renders the hand-drawn nirslam.svg to the 256x256 PNG that the package installs next to it (run after
# editing the SVG, commit both). ImageMagick is called as /usr/bin/convert on purpose: it is the
# Debian package's binary (install-deps.sh installs imagemagick), never a stand-in earlier on PATH.
set -euo pipefail
cd "$(dirname "$0")"
/usr/bin/convert -background none nirslam.svg -resize 256x256 -depth 8 -strip png32:nirslam.png
echo "wrote $(pwd)/nirslam.png"
