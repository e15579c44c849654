#!/usr/bin/env bash
# Cross-architecture determinism check.
#
# Builds lockstep-core's tests and the `lockstep` CLI for i686 and aarch64
# (statically linked; aarch64 runs under qemu-user), runs the core tests on
# both, then steps every example scene for TICKS ticks on x86_64, i686 and
# aarch64 and fails if any hash line differs.
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

for t in "${targets[@]}"; do
  echo "cross-arch: lockstep-core tests on $t"
  cargo test -q -p lockstep-core --target "$t"
done

out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
cargo build -q --release -p lockstep --bin lockstep
for t in "${targets[@]}"; do
  cargo build -q --release -p lockstep --bin lockstep --target "$t"
done

run() { # arch scene
  case "$1" in
    x86_64) target/release/lockstep sim --scene "$2" --ticks "$ticks" ;;
    i686) "target/i686-unknown-linux-gnu/release/lockstep" sim --scene "$2" --ticks "$ticks" ;;
    aarch64) qemu-aarch64 "target/aarch64-unknown-linux-gnu/release/lockstep" sim --scene "$2" --ticks "$ticks" ;;
  esac
}

status=0
for scene in scenes/*.toml; do
  name=$(basename "$scene" .toml)
  for arch in x86_64 i686 aarch64; do
    run "$arch" "$scene" >"$out/$name.$arch"
  done
  lines=$(wc -l <"$out/$name.x86_64")
  if [ "$lines" -ne "$ticks" ]; then
    echo "cross-arch: FAIL $name: x86_64 printed $lines hash lines, expected $ticks"
    status=1
    continue
  fi
  for arch in i686 aarch64; do
    if ! cmp -s "$out/$name.x86_64" "$out/$name.$arch"; then
      first=$(diff <(cat "$out/$name.x86_64") <(cat "$out/$name.$arch") | head -3 | tr '\n' ' ')
      echo "cross-arch: FAIL $name: $arch differs from x86_64: $first"
      status=1
    fi
  done
  [ $status -ne 0 ] || echo "cross-arch: ok $name: $ticks ticks, x86_64 = i686 = aarch64, final $(tail -1 "$out/$name.x86_64")"
done
exit $status
