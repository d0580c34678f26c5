#!/usr/bin/env bash
# Renders the CLI test scenes in every mode and prints one line per image:
# "<case> <sha256 of the PNG>" (the PNG encoder is deterministic). Run it on two builds (same
# profile: debug and release shaders differ in rounding) and diff the
# outputs to show a refactor left every image unchanged:
#   tools/image-hashes.sh target/release/sphereshade > before.txt
set -euo pipefail
bin=${1:-target/release/sphereshade}
here=$(cd "$(dirname "$0")/.." && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$tmp}
printf '# two\n-3 0 0 2\n3 0 0 2\n' > "$tmp/two.xyzr"
scenes=(
  "random:--scene random --atoms 500 --width 96 --height 64"
  "two:$tmp/two.xyzr --width 64 --height 32"
  "1tii:$here/tests/data/1tii.pdb --width 128 --height 96"
)
for sc in "${scenes[@]}"; do
  name=${sc%%:*}; args=${sc#*:}
  for shadows in none issm issm-soft deep sm-pcf osm; do
    for ssdo in off plain semantic; do
      for aov in color id depth shadow ao; do
        out="$tmp/$name-$shadows-$ssdo-$aov.png"
        # shellcheck disable=SC2086
        "$bin" render $args --shadows "$shadows" --ssdo "$ssdo" --aov "$aov" --out "$out" 2>/dev/null
        echo "$name-$shadows-$ssdo-$aov $(sha256sum "$out" | cut -c1-16)"
      done
    done
  done
  for extra in "--shadows deep --opacity 0.5" "--shadows osm --opacity 0.5" "--raster graphics" "--blur off" "--fov 40"; do
    out="$tmp/x.png"
    # shellcheck disable=SC2086
    "$bin" render $args $extra --out "$out" 2>/dev/null
    echo "$name ${extra// /_} $(sha256sum "$out" | cut -c1-16)"
  done
done
