#!/usr/bin/env bash
# CI's packaging stage (issue 12): builds the Debian package in a Release build tree, installs it with
# apt, runs the installed /usr/bin/nirslam from a temporary folder outside the source tree (--version,
# simulate, run, eval, a headless GUI screenshot, the man page, bash completion), then removes the
# package and checks that every file it installed is gone. Any failure exits non-zero.
#
#   packaging/check-package.sh [BUILD_DIR]     (default: build; a configured Release build tree)
#
# Installs into the system (/usr): run it on a CI or development machine, as root or with sudo.
set -euo pipefail

source_dir=$(cd "$(dirname "$0")/.." && pwd)
build_dir=$(cd "${1:-$source_dir/build}" && pwd)
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
export DEBIAN_FRONTEND=noninteractive

started=$(date +%s)
step() { printf -- '--- %s (%ss)\n' "$*" "$(($(date +%s) - started))"; }
fail() {
  echo "check-package: FAILED: $*" >&2
  exit 1
}
is_installed() { dpkg-query -W -f='${Status}' nirslam 2> /dev/null | grep -q "install ok installed"; }

work=""
cleanup() {
  local status=$?
  cd /
  [ -n "$work" ] && rm -rf "$work"
  # A failed check must not leave a half-checked nirslam in /usr for the next run.
  if [ $status -ne 0 ] && is_installed; then "${sudo_cmd[@]}" apt-get remove -y -qq nirslam > /dev/null || true; fi
  exit $status
}
trap cleanup EXIT

step "Package: cpack -G DEB in $build_dir"
cmake --build "$build_dir" --target nirslam nirslam_manpage -j"$(nproc)" > /dev/null
rm -f "$build_dir"/nirslam_*.deb
(cd "$build_dir" && cpack -G DEB > cpack.log 2>&1) || {
  cat "$build_dir/cpack.log"
  fail "cpack failed"
}
debs=("$build_dir"/nirslam_*.deb)
[ ${#debs[@]} -eq 1 ] && [ -f "${debs[0]}" ] || fail "expected one nirslam_*.deb in $build_dir, found: ${debs[*]}"
deb=${debs[0]}
dpkg-deb --field "$deb" Package Version Architecture Section Maintainer Installed-Size Depends Suggests
depends=$(dpkg-deb --field "$deb" Depends)
# From dpkg-shlibdeps (the linked libraries) and the runtime-only Mesa EGL vendor and DRI drivers.
for dependency in libc6 libstdc++6 libopencv-core libglfw3 libegl1 libopengl0 libyaml-cpp libzip4 libpng16-16 \
  libjpeg62-turbo libegl-mesa0 libgl1-mesa-dri; do
  [[ $depends == *"$dependency"* ]] || fail "Depends lacks $dependency: $depends"
done
# Image files go through libpng / libjpeg: OpenCV's imgcodecs would bring GDAL and ~118 libraries.
[[ $depends != *imgcodecs* && $depends != *gdal* ]] || fail "Depends pulls in imgcodecs or GDAL: $depends"

step "Install: apt-get install $deb"
if is_installed; then "${sudo_cmd[@]}" apt-get remove -y -qq nirslam > /dev/null; fi
"${sudo_cmd[@]}" apt-get install -y -qq "$deb" > "$build_dir/apt-install.log" 2>&1 || {
  cat "$build_dir/apt-install.log"
  fail "apt-get install failed"
}
is_installed || fail "nirslam is not installed after apt-get install"
mapfile -t installed_files < <(dpkg -L nirslam | while read -r path; do if [ -f "$path" ]; then echo "$path"; fi; done)
for expected in /usr/bin/nirslam /usr/share/nirslam/shaders/scene.frag /usr/share/nirslam/config/pipeline.yaml \
  /usr/share/nirslam/config/illumination.yaml /usr/share/man/man1/nirslam.1.gz \
  /usr/share/applications/nirslam.desktop /usr/share/icons/hicolor/scalable/apps/nirslam.svg \
  /usr/share/icons/hicolor/256x256/apps/nirslam.png /usr/share/bash-completion/completions/nirslam \
  /usr/share/doc/nirslam/copyright; do
  [[ " ${installed_files[*]} " == *" $expected "* ]] || fail "the package does not install $expected"
done
echo "${#installed_files[@]} files installed"

work=$(mktemp -d)
case "$work" in "$source_dir"/* | "$build_dir"/*) fail "temp folder $work is inside the source or build tree" ;; esac
cd "$work"
nirslam=/usr/bin/nirslam

step "Run: --version"
"$nirslam" --version | tee version.txt
[ "$(head -n 1 version.txt)" = "nirslam $(dpkg-deb --field "$deb" Version)" ] || fail "--version's first line"
for field in "git" "commit" "build type" "compiler" "build date" "Dear ImGui" "OpenCV" "Eigen"; do
  grep -q "^$field: ." version.txt || fail "--version has no '$field:' line"
done

step "Run: simulate"
"$nirslam" simulate --scene tunnel --frames 60 --width 320 --height 240 --supersampling 1 -o tunnel > simulate.log 2>&1 ||
  { cat simulate.log; fail "simulate"; }
[ -f tunnel/groundtruth.txt ] && [ -f tunnel/images/00059.png ] || fail "simulate wrote no sequence"

step "Run: run (shipped config and data found under /usr/share/nirslam)"
"$nirslam" -v run tunnel -o tunnel-run > run.log 2>&1 || { cat run.log; fail "run"; }
grep -q "config folder: /usr/share/nirslam/config" run.log || { cat run.log; fail "run did not use /usr/share/nirslam/config"; }
for output in summary.json quality.csv trajectory.txt; do
  [ -s "tunnel-run/$output" ] || fail "run wrote no $output"
done
"$nirslam" eval tunnel-run/trajectory.txt tunnel/groundtruth.txt > eval.log 2>&1 || { cat eval.log; fail "eval"; }
grep -E "^ *(measure|ATE)" eval.log || fail "eval printed no ATE"

step "Run: gui --headless --screenshot"
"$nirslam" -v gui tunnel --headless --frames 10 --size 800x500 --screenshot shot.png > gui.log 2>&1 || { cat gui.log; fail "gui"; }
grep -q "shaders folder: /usr/share/nirslam/shaders" gui.log || { cat gui.log; fail "gui did not use /usr/share/nirslam/shaders"; }
shot_bytes=$(stat -c %s shot.png 2> /dev/null || echo 0)
[ "$shot_bytes" -gt 20000 ] || fail "screenshot missing or tiny ($shot_bytes bytes)"
echo "screenshot: $shot_bytes bytes"

step "Man page, completion, desktop entry"
[ "$(man -w nirslam)" = /usr/share/man/man1/nirslam.1.gz ] || fail "man -w nirslam: $(man -w nirslam 2>&1)"
# groff warnings (-ww) would show as text on the reader's terminal; -z: check only, no output.
warnings=$(zcat /usr/share/man/man1/nirslam.1.gz | groff -man -Tutf8 -ww -z 2>&1)
[ -z "$warnings" ] || fail "man page has groff warnings: $warnings"
MANWIDTH=80 man -P cat nirslam 2> /dev/null | grep -q "nirslam run" || fail "man page lacks the subcommand sections"
completions=$(bash -c 'source /usr/share/bash-completion/completions/nirslam &&
  COMP_LINE="nirslam re"; COMP_POINT=${#COMP_LINE}; _nirslam; echo "${COMPREPLY[*]}"')
[ "$completions" = "record recover" ] || fail "completion of 'nirslam re' gave '$completions' (expected 'record recover')"
if command -v desktop-file-validate > /dev/null; then desktop-file-validate /usr/share/applications/nirslam.desktop; fi

step "Remove: apt-get remove nirslam"
cd /
"${sudo_cmd[@]}" apt-get remove -y -qq nirslam > "$build_dir/apt-remove.log" 2>&1 || {
  cat "$build_dir/apt-remove.log"
  fail "apt-get remove failed"
}
! is_installed || fail "nirslam still installed"
for path in "${installed_files[@]}"; do
  [ ! -e "$path" ] || fail "$path is still there after apt-get remove"
done
[ ! -e /usr/share/nirslam ] || fail "/usr/share/nirslam is still there after apt-get remove"
step "Package checked: ${#installed_files[@]} files installed, used and removed"
