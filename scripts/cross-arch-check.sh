#!/usr/bin/env bash
# Cross-architecture determinism check.
#
# Builds lockstep-core's tests and its `scene_hashes` example for i686 and
# aarch64 (statically linked; aarch64 runs under qemu-user), runs the core
# tests on both, then steps every example scene and seeded random scenes
# 1..20 for TICKS ticks on x86_64, i686 and aarch64 and fails if any hash
# line differs; on x86_64 the example's lines are also compared with the
# `lockstep sim` CLI's. The example needs nothing but lockstep-core, so the
# cross builds do not compile the server's network stack twice more.
#
# Installs what it needs (rustup targets, Debian cross compilers, qemu-user)
# when missing. Usage: scripts/cross-arch-check.sh [TICKS]   (default 1000)
set -euo pipefail
cd "$(dirname "$0")/.."
ticks="${1:-1000}"
targets=(i686-unknown-linux-gnu aarch64-unknown-linux-gnu)

need=()
command -v i686-linux-gnu-gcc >/dev/null || need+=(gcc-i686-linux-gnu libc6-dev-i386-cross)
command -v aarch64-linux-gnu-gcc >/dev/null || need+=(gcc-aarch64-linux-gnu libc6-dev-arm64-cross)
command -v qemu-aarch64 >/dev/null || need+=(qemu-user)
if [ ${#need[@]} -gt 0 ]; then
  echo "cross-arch: installing ${need[*]}"
  sudo_cmd=""
  [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
  $sudo_cmd apt-get update -q >/dev/null
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -q "${need[@]}" >/dev/null
fi
installed=$(rustup target list --installed)
for t in "${targets[@]}"; do
  grep -qx "$t" <<<"$installed" || rustup target add "$t"
done

export CARGO_TARGET_I686_UNKNOWN_LINUX_GNU_LINKER=i686-linux-gnu-gcc
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
export CARGO_TARGET_I686_UNKNOWN_LINUX_GNU_RUSTFLAGS="-C target-feature=+crt-static"
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUSTFLAGS="-C target-feature=+crt-static"
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER=qemu-aarch64

# Under qemu-user the tests run about ten times slower than natively: there,
# the three unit tests that compare the narrow phase with f64 references over
# thousands of random poses (natively 48 of the unit tests' 69 s) are left to
# the native and i686 runs (the scene hashes below still compare the narrow
# phase's results on aarch64, through every example and random scene).
qemu_skip=(
  --skip sphere_and_capsule_depths_match_f64_closest_points_over_seeded_poses
  --skip gjk_distance_matches_brute_force_over_1000_random_poses_per_pair_kind
  --skip hull_contacts_agree_with_the_references_and_lie_on_both_surfaces
)
for t in "${targets[@]}"; do
  echo "cross-arch: lockstep-core tests on $t ($SECONDS s in)"
  # Unit and integration tests; the doctests are examples for the reader,
  # run natively by `cargo test` (rustdoc does not cross-run them here).
  if [ "$t" = aarch64-unknown-linux-gnu ]; then
    cargo test -q -p lockstep-core --target "$t" --lib --tests -- "${qemu_skip[@]}"
  else
    cargo test -q -p lockstep-core --target "$t" --lib --tests
  fi
done

echo "cross-arch: building the lockstep CLI natively and scene_hashes for x86_64, ${targets[*]} ($SECONDS s in)"
td="${CARGO_TARGET_DIR:-target}"
cargo build -q --release -p lockstep --bin lockstep
cargo build -q --release -p lockstep-core --example scene_hashes
for t in "${targets[@]}"; do
  cargo build -q --release -p lockstep-core --example scene_hashes --target "$t"
done

out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
run() { # arch args...
  local arch=$1
  shift
  case "$arch" in
    cli) "$td/release/lockstep" sim "$@" --ticks "$ticks" ;;
    x86_64) "$td/release/examples/scene_hashes" "$@" --ticks "$ticks" ;;
    i686) "$td/i686-unknown-linux-gnu/release/examples/scene_hashes" "$@" --ticks "$ticks" ;;
    aarch64) qemu-aarch64 "$td/aarch64-unknown-linux-gnu/release/examples/scene_hashes" "$@" --ticks "$ticks" ;;
  esac
}

status=0
check() { # name what archs args...
  local name=$1 what=$2 archs=$3 arch first
  shift 3
  for arch in $archs; do
    run "$arch" "$@" >"$out/$name.$arch" || echo "cross-arch: $what: $arch exited with an error"
  done
  local lines
  lines=$(wc -l <"$out/$name.x86_64")
  if [ "$lines" -ne "$ticks" ]; then
    echo "cross-arch: FAIL $what: x86_64 printed $lines hash lines, expected $ticks"
    status=1
    return
  fi
  local ok=1
  for arch in $archs; do
    [ "$arch" = x86_64 ] && continue
    if ! cmp -s "$out/$name.x86_64" "$out/$name.$arch"; then
      first=$(diff "$out/$name.x86_64" "$out/$name.$arch" | head -3 | tr '\n' ' ')
      echo "cross-arch: FAIL $what: $arch differs from x86_64: $first"
      status=1 ok=0
    fi
  done
  [ $ok -eq 0 ] || echo "cross-arch: ok $what: $ticks ticks, ${archs// / = }, final $(tail -1 "$out/$name.x86_64")"
}
for scene in scenes/*.toml; do
  name=$(basename "$scene" .toml)
  check "$name" "$name" "x86_64 cli i686 aarch64" --scene "$scene"
done
for seed in $(seq 1 20); do
  check "random$seed" "random scene $seed" "x86_64 i686 aarch64" --random "$seed"
done

# --- wasm32 -----------------------------------------------------------------
# The fourth architecture, two ways, on every example scene and on seeded
# random scenes 1..20 (sphere, box, capsule and hull bodies, dynamic and
# static, built through the core API from integers), TICKS ticks each:
# - wasm32-wasip1: core's `scene_hashes` example (it needs nothing but
#   lockstep-core) under Node's WASI (scripts/wasi-run.mjs);
# - wasm32-unknown-unknown, the browser target: core's `plain_exports`
#   example, a module that imports nothing (so no threads, files or clocks),
#   driven from JS through its exports (scripts/plain-exports-run.mjs);
# each compared with `scene_hashes` built natively; fails if any hash line
# differs. The native scene lines are also checked against the golden files
# (every 50th tick), so the example steps scenes as `lockstep sim` does.
# lockstep-proto must build for wasm32-unknown-unknown too.
# Installs the two rustup targets, and Debian's nodejs if `node` is missing.
wasm32_check() {
  local target_dir="${CARGO_TARGET_DIR:-target}"
  local native="$target_dir/release/examples/scene_hashes"
  local wasi="$target_dir/wasm32-wasip1/release/examples/scene_hashes.wasm"
  local plain="$target_dir/wasm32-unknown-unknown/release/examples/plain_exports.wasm"
  local installed t
  if ! command -v node >/dev/null; then
    echo "cross-arch: installing nodejs"
    local sudo_cmd=""
    [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
    $sudo_cmd apt-get update -q >/dev/null
    DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -q nodejs >/dev/null
  fi
  installed=$(rustup target list --installed)
  for t in wasm32-wasip1 wasm32-unknown-unknown; do
    grep -qx "$t" <<<"$installed" || rustup target add "$t"
  done

  echo "cross-arch: building scene_hashes natively; lockstep-core, lockstep-proto and the examples for wasm32-wasip1 and wasm32-unknown-unknown"
  cargo build -q --release -p lockstep-core --example scene_hashes
  # One invocation for both wasm targets, so their builds overlap.
  cargo build -q --release -p lockstep-core -p lockstep-proto --lib \
    --example scene_hashes --example plain_exports \
    --target wasm32-wasip1 --target wasm32-unknown-unknown

  local dir fail=0 compared=0 name what golden flavour
  dir=$(mktemp -d)
  compare() { # name what args...
    name=$1 what=$2
    shift 2
    compared=$((compared + 1))
    if ! "$native" "$@" --ticks "$ticks" >"$dir/$name.native"; then
      echo "cross-arch: FAIL $what: the native example failed"
      fail=1
      return
    fi
    if [ "$(wc -l <"$dir/$name.native")" -ne "$ticks" ]; then
      echo "cross-arch: FAIL $what: native printed $(wc -l <"$dir/$name.native") hash lines, expected $ticks"
      fail=1
      return
    fi
    node scripts/wasi-run.mjs "$wasi" "$@" --ticks "$ticks" >"$dir/$name.wasm32-wasip1" || true
    node scripts/plain-exports-run.mjs "$plain" "$@" --ticks "$ticks" >"$dir/$name.wasm32-unknown-unknown" || true
    local ok=1
    for flavour in wasm32-wasip1 wasm32-unknown-unknown; do
      if ! cmp -s "$dir/$name.native" "$dir/$name.$flavour"; then
        echo "cross-arch: FAIL $what: $flavour differs from x86_64: $(diff "$dir/$name.native" "$dir/$name.$flavour" | head -3 | tr '\n' ' ')"
        fail=1 ok=0
      fi
    done
    [ $ok -eq 0 ] || echo "cross-arch: ok $what: $ticks ticks, x86_64 = wasm32-wasip1 = wasm32-unknown-unknown, final $(tail -1 "$dir/$name.native")"
  }
  for scene in scenes/*.toml; do
    name=$(basename "$scene" .toml)
    compare "$name" "$name" --scene "$scene"
    golden="tests/golden/$name.hashes"
    if [ -f "$golden" ] && ! cmp -s \
      <(awk '$2 % 50 == 0 && $2 <= 1000' "$dir/$name.native") \
      <(awk -v n="$ticks" '$2 <= n' "$golden"); then
      echo "cross-arch: FAIL $name: the example's native hashes differ from $golden"
      fail=1
    fi
  done
  for seed in $(seq 1 20); do
    compare "random$seed" "random scene $seed" --random "$seed"
  done
  rm -rf "$dir"
  [ $fail -ne 0 ] || echo "cross-arch: ok wasm32: $compared scenes, x86_64 = wasm32-wasip1 = wasm32-unknown-unknown (under node $(node --version))"
  wasm32_status=$fail
}
wasm32_status=0
wasm32_check
[ $wasm32_status -eq 0 ] || status=1
exit $status
