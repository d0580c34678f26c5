#!/usr/bin/env bash
# Renders the CLI test scenes with two builds and reports, per case, the
# share of pixels that differ by more than 2 % and the largest channel
# difference, writing difference images to target/compare/ (ImageMagick's
# `compare`; apt-get install imagemagick):
#   tools/compare-builds.sh OLD_BINARY NEW_BINARY
set -euo pipefail
old=$1 new=$2
here=$(cd "$(dirname "$0")/.." && pwd)
out=$here/target/compare
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$tmp}
printf '# two\n-3 0 0 2\n3 0 0 2\n' > "$tmp/two.xyzr"
scenes=(
  "random:--scene random --atoms 500 --width 96 --height 64"
  "1tii:$here/tests/data/1tii.pdb --width 256 --height 192"
  # spheres ~16 px in radius: SSDO per 2x2 block
  "1tii-close:$here/tests/data/1tii.pdb --width 256 --height 192 --view-height 20"
)
printf '%-34s %10s %8s\n' case "px>2%" "max"
for sc in "${scenes[@]}"; do
  name=${sc%%:*}; args=${sc#*:}
  for shadows in none issm issm-soft deep sm-pcf osm; do
    for ssdo in off plain semantic; do
      for aov in color shadow ao; do
        c="$name-$shadows-$ssdo-$aov"
        # shellcheck disable=SC2086
        "$old" render $args --shadows "$shadows" --ssdo "$ssdo" --aov "$aov" --out "$tmp/o.png" 2>/dev/null
        # shellcheck disable=SC2086
        "$new" render $args --shadows "$shadows" --ssdo "$ssdo" --aov "$aov" --out "$tmp/n.png" 2>/dev/null
        total=$(identify -format '%[fx:w*h]' "$tmp/o.png")
        ae=$(compare -metric AE -fuzz 2% "$tmp/o.png" "$tmp/n.png" "$out/$c-diff.png" 2>&1 || true)
        mx=$(compare -metric PAE "$tmp/o.png" "$tmp/n.png" null: 2>&1 | sed 's/.*(\(.*\))/\1/' || true)
        printf '%-34s %9.2f%% %8s\n' "$c" "$(echo "100 * $ae / $total" | bc -l)" "$mx"
      done
    done
  done
done
