#!/bin/sh
# The look against Debian's tachyon ray tracer (issue "Images people
# publish"): for each file, white .xyzr spheres at 640x480 with the default
# modes against Tachyon (same camera and key light, hard shadows, 64-sample
# sky-light AO). Prints the luminance rank correlation and spread (goals:
# >= 0.9 and >= 0.6x Tachyon's) and writes side-by-side pictures to
# target/look/. Extra arguments go to every run (e.g. --ssdo plain).
#   tools/look-vs-tachyon.sh [FILE ...] [-- OPTIONS]   (e.g. -- --hierarchy --ssdo plain)
set -eu
cd "$(dirname "$0")/.."
command -v tachyon >/dev/null || { echo "tachyon is missing: run tools/setup.sh" >&2; exit 1; }
files=""
while [ $# -gt 0 ] && [ "$1" != "--" ]; do files="$files $1"; shift; done
[ "${1:-}" = "--" ] && shift
[ -n "$files" ] || files="tests/data/1tii.pdb tests/data/pdb3p3w.pdb"
cargo build --release --example look_vs_tachyon -q
for f in $files; do
    target/release/examples/look_vs_tachyon "$f" --width 640 --height 480 "$@"
done
