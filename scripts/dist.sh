#!/usr/bin/env bash
# Release FMUs for every platform, one .fmu per model and FMI version carrying every platform's binary:
#
#   target/dist/fmi2/{BacklashPlant,MrgiaEstimator,BacklashCompensator}.fmu   binaries/linux64, win64, darwin64
#   target/dist/fmi3/{BacklashPlant,MrgiaEstimator,BacklashCompensator}.fmu   x86_64-linux, x86_64-windows, aarch64-linux,
#                                                         x86_64-darwin, aarch64-darwin
#
# Installs what it needs on a fresh Debian/Ubuntu machine: the mingw-w64 linker, zig and cargo-zigbuild (PyPI,
# into .venv), and Rust for the two cross targets. Rust: rustup's standard library for the target when rustup
# can install it; otherwise Debian's rustc-web with its source (rust-web-src), building the standard library
# for the target (`-Zbuild-std`, enabled on a stable compiler with RUSTC_BOOTSTRAP=1). BACKLASH_DIST_RUST=debian
# forces the second route. Each platform's library is built once, from the FMU-only library
# (`--no-default-features`, profile `fmu`: no debug information, stripped):
#
#   x86_64 Linux   cargo build --release --package backlash-fmu-packaging (packaging/build.rs: cargo zigbuild,
#                  GLIBC 2.17), also target/fmu, target/fmu3
#   x86_64 Windows cargo build --target x86_64-pc-windows-gnu, linked by x86_64-w64-mingw32-gcc; libgcc and
#                  winpthread linked in statically, so the DLL imports only DLLs every Windows has
#   aarch64 Linux  cargo zigbuild --target aarch64-unknown-linux-gnu.2.17 (GLIBC 2.17)
#   macOS          x86_64-apple-darwin and aarch64-apple-darwin (rustup's standard library only), linked by
#                  rust-lld (ld64 flavour, which signs arm64 ad hoc) against a stub of libSystem made from
#                  zig's (scripts/macos_sdk_stub.py); checked structurally only (tests/cross/test_dist.py)
#
# For speed on a 2-core machine, Windows and both macOS targets are one cargo build (one job graph keeps both
# cores busy where a single target's build waits on one crate), and the aarch64 build runs beside it in a
# target directory of its own (cargo locks a target directory for one build at a time).
#
# scripts/merge_fmus.py then puts the binaries beside the Linux one in the FMUs that the packaging build
# packaged. The FMUs are checked by tests/cross (scripts/cross_test.sh runs them under Wine and QEMU).
set -euo pipefail
cd "$(dirname "$0")/.."
start=$SECONDS
say() { printf '== dist [%3ds] %s\n' $((SECONDS - start)) "$*"; }

say "toolchain"
bash scripts/apt_install.sh gcc-mingw-w64-x86-64 python3-venv
command -v cargo >/dev/null || bash scripts/apt_install.sh rustc-web cargo-web
[ -x .venv/bin/python ] || python3 -m venv .venv
.venv/bin/python -m pip install -q --disable-pip-version-check -r scripts/requirements-cross.txt
venv_bin="$PWD/.venv/bin"

# rustup's standard library for every cross target, when rustup can install it; else (or with
# BACKLASH_DIST_RUST=debian) Debian's rustc-web builds std for Windows and aarch64 (-Zbuild-std) and macOS is
# left out (the FMUs then lack it, and tests/cross says so).
cross=(x86_64-pc-windows-gnu aarch64-unknown-linux-gnu x86_64-apple-darwin aarch64-apple-darwin)
rustup_has_all() {
    [ "${BACKLASH_DIST_RUST:-}" != debian ] && command -v rustup >/dev/null || return 1
    local installed
    installed=$(rustup target list --installed)
    for t in "${cross[@]}"; do
        grep -qx "$t" <<<"$installed" || rustup target add "$t" >/dev/null 2>&1 || return 1
    done
}
rust_env=()
build_std=()
macos=1
if ! rustup_has_all; then
    bash scripts/apt_install.sh rustc-web cargo-web rust-web-src
    echo "   rustup cannot install the cross targets' standard library here: Debian's rustc-web builds it" \
        "(-Zbuild-std); macOS is left out (Apple's is only in rustup)" >&2
    rust_env=(PATH="/usr/bin:$venv_bin:$PATH" CARGO=/usr/bin/cargo RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1)
    build_std=(-Zbuild-std=std,panic_unwind)
    macos=0
fi

# The FMU-only library, as packaging/build.rs builds it (build/package.rs), for the other targets. BACKLASH_FMU_NESTED
# tells the build scripts that this is that build (no packaging inside it). The flags are the project's own: RUSTFLAGS
# from the caller would override the per-target flags below.
unset RUSTFLAGS CARGO_ENCODED_RUSTFLAGS
lib_args=(--package backlash-fmu --profile fmu --lib --no-default-features)

# Only the packaging package: its build script builds and packages the FMU library; the crate's own release
# build (the program) is not needed here, and a caller that built it with other dependency features (the tests'
# set, scripts/test.sh) would have it compiled again.
say "x86_64 Linux: the packaging package (the FMUs of target/fmu and target/fmu3)"
BACKLASH_FMU_PORTABLE=require cargo build --release --package backlash-fmu-packaging

say "aarch64 Linux (cargo zigbuild, in the background, log target/fmu-build-zig.log)"
env BACKLASH_FMU_NESTED=1 PATH="$venv_bin:$PATH" "${rust_env[@]}" "$venv_bin/cargo-zigbuild" zigbuild \
    "${lib_args[@]}" --target-dir target/fmu-build-zig --target aarch64-unknown-linux-gnu.2.17 "${build_std[@]}" \
    >target/fmu-build-zig.log 2>&1 &
zig_pid=$!
trap 'kill "$zig_pid" 2>/dev/null || true' EXIT  # a failed build below leaves no build running behind it
arm=target/fmu-build-zig/aarch64-unknown-linux-gnu/fmu/libbacklash.so

# macOS: zig's own Mach-O linker ignores -exported_symbols_list (the dylib would export every Rust symbol) and
# does not sign; rust-lld does both. SDKROOT: the stub of libSystem it links against.
targets=(--target x86_64-pc-windows-gnu)
mac_env=()
if ((macos)); then
    .venv/bin/python scripts/macos_sdk_stub.py target/macos-sdk
    lld="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin/rust-lld"
    mac_flags="-C linker-flavor=ld64.lld -C link-arg=-install_name -C link-arg=@rpath/libbacklash.dylib"
    for t in X86_64_APPLE_DARWIN AARCH64_APPLE_DARWIN; do
        mac_env+=("CARGO_TARGET_${t}_LINKER=$lld" "CARGO_TARGET_${t}_RUSTFLAGS=$mac_flags")
    done
    mac_env+=(SDKROOT="$PWD/target/macos-sdk")
    targets+=(--target x86_64-apple-darwin --target aarch64-apple-darwin)
fi
say "Windows x64 (mingw-w64)${mac_env:+, macOS x86_64 and arm64 (rust-lld)}: one cargo build"
env BACKLASH_FMU_NESTED=1 "${rust_env[@]}" "${mac_env[@]}" \
    CARGO_TARGET_X86_64_PC_WINDOWS_GNU_LINKER=x86_64-w64-mingw32-gcc \
    cargo build "${lib_args[@]}" --target-dir target/fmu-build "${targets[@]}" "${build_std[@]}"
win=target/fmu-build/x86_64-pc-windows-gnu/fmu/backlash.dll
mac_x86=target/fmu-build/x86_64-apple-darwin/fmu/libbacklash.dylib
mac_arm=target/fmu-build/aarch64-apple-darwin/fmu/libbacklash.dylib

say "waiting for the aarch64 build"
if ! wait "$zig_pid"; then
    cat target/fmu-build-zig.log >&2
    echo "dist: the aarch64 build failed (log above, target/fmu-build-zig.log)" >&2
    exit 1
fi
tail -n 1 target/fmu-build-zig.log

say "merge into target/dist"
fmi2=(--binary "win64=$win")
fmi3=(--binary "x86_64-windows=$win" --binary "aarch64-linux=$arm")
if ((macos)); then
    fmi2+=(--binary "darwin64=$mac_x86")
    fmi3+=(--binary "x86_64-darwin=$mac_x86" --binary "aarch64-darwin=$mac_arm")
fi
rm -rf target/dist
for model in BacklashPlant MrgiaEstimator BacklashCompensator; do
    .venv/bin/python scripts/merge_fmus.py "target/dist/fmi2/$model.fmu" "target/fmu/$model.fmu" "${fmi2[@]}"
    .venv/bin/python scripts/merge_fmus.py "target/dist/fmi3/$model.fmu" "target/fmu3/$model.fmu" "${fmi3[@]}"
done
say "done"
