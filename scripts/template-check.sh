#!/usr/bin/env bash
# The example game as a team's copy: copied out of the repository into a
# temporary folder, its path dependencies pointed at this checkout (what a
# team does, or it uses a git dependency), built and tested there on its own
# (no workspace above it). Usage: scripts/template-check.sh
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
copy="$work/my-game"
cp -r "$repo/example-game" "$copy"
sed -i "s|path = \"\.\./|path = \"$repo/|" "$copy/Cargo.toml"
# The same dependency versions as the repository's (the copy's own lock
# file is then pruned to what it uses).
cp "$repo/Cargo.lock" "$copy/"
cd "$copy"
# The workspace's own target folder: the copy's profiles are the workspace's
# (example-game/.cargo/config.toml), so every dependency built with the same
# features is reused, not built again (about 20 crates differ in features
# and are built beside the workspace's). The copy's binary has the
# workspace's name; cargo links the workspace's back on its next build.
export CARGO_TARGET_DIR="$repo/target"
cargo test -q
echo "template: the copy in $copy built and passed its tests"
