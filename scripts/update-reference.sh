#!/usr/bin/env bash
# Re-renders the reference image of the offscreen test (crates/cloth-view/tests/offscreen.rs):
# the drape at resolution 32 after 120 frames, 320x240. Run it after an intended change to the
# renderer or the physics, look at the image, and commit it.
# usage: scripts/update-reference.sh
set -euo pipefail
cd "$(dirname "$0")/.."
out=crates/cloth-view/tests/reference/drape.png
cargo run --quiet --bin cloth -- render drape --frames 120 --resolution 32 --size 320x240 --png "$out"
echo "updated $out: look at it before committing"
