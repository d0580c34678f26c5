#!/bin/bash
# Packs what tools/gpu-goals.sh needs on a lent GPU machine (the `device`
# tool), here, before the one call: the release binary, stripped and
# xz-compressed into .gpu/ (~3.2 MB: the tracked tree is ~63 MB of the 64 MiB
# a call may carry), and the Vulkan loader's .deb into .gl/ (the machine has
# NVIDIA's driver but maybe no loader). Both folders are ignored through
# .git/info/exclude, so only `carry` takes them along:
#   run(command="bash tools/gpu-goals.sh", carry=[".gpu", ".gl"], timeout_s=540)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release
mkdir -p .gpu .gl /tmp/amd64/partial
for d in /.gpu/ /.gl/; do
  grep -qxF "$d" .git/info/exclude 2>/dev/null || echo "$d" >> .git/info/exclude
done
strip -o .gpu/sphereshade target/release/sphereshade
xz -9e -f -T2 .gpu/sphereshade
o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
# shellcheck disable=SC2086
apt-get $o update -qq
rm -f .gl/*.deb
# shellcheck disable=SC2086
(cd .gl && apt-get $o download libvulkan1)
tracked=$(git ls-files -z | xargs -0 du -cb | tail -1 | cut -f1)
packed=$(du -cb .gpu .gl | tail -1 | cut -f1)
total=$((tracked + packed))
echo "gpu-pack: tracked $tracked + packed $packed = $total bytes (a call carries at most $((64 << 20)))"
if [ "$total" -gt $((64 << 20)) ]; then echo "gpu-pack: too large to carry" >&2; exit 1; fi
