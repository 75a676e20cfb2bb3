#!/usr/bin/env bash
# Release FMUs for every platform, one .fmu per model and FMI version carrying every platform's binary:
#
#   target/dist/fmi2/{BacklashPlant,MrgiaEstimator}.fmu   binaries/linux64, win64, darwin64
#   target/dist/fmi3/{BacklashPlant,MrgiaEstimator}.fmu   x86_64-linux, x86_64-windows, aarch64-linux,
#                                                         x86_64-darwin, aarch64-darwin
#
# Installs what it needs on a fresh Debian/Ubuntu machine: the mingw-w64 linker, zig and cargo-zigbuild (PyPI,
# into .venv), and Rust for the two cross targets. Rust: rustup's standard library for the target when rustup
# can install it; otherwise Debian's rustc-web with its source (rust-web-src), building the standard library
# for the target (`-Zbuild-std`, enabled on a stable compiler with RUSTC_BOOTSTRAP=1). BACKLASH_DIST_RUST=debian
# forces the second route. Each platform's library is built once, from the FMU-only library
# (`--no-default-features`, profile `fmu`: no debug information, stripped):
#
#   x86_64 Linux   cargo build --release (build.rs: cargo zigbuild, GLIBC 2.17), also target/fmu, target/fmu3
#   x86_64 Windows cargo build --target x86_64-pc-windows-gnu, linked by x86_64-w64-mingw32-gcc; libgcc and
#                  winpthread linked in statically, so the DLL imports only DLLs every Windows has
#   aarch64 Linux  cargo zigbuild --target aarch64-unknown-linux-gnu.2.17 (GLIBC 2.17)
#   macOS          x86_64-apple-darwin and aarch64-apple-darwin (rustup's standard library only), linked by
#                  rust-lld (ld64 flavour, which signs arm64 ad hoc) against a stub of libSystem made from
#                  zig's (scripts/macos_sdk_stub.py); checked structurally only (tests/cross/test_dist.py)
#
# and scripts/merge_fmus.py puts the binaries beside the Linux one in the FMUs that `cargo build --release`
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

# How to build for one cross target: sets `rust_env` (variables for cargo) and `build_std` (its extra flags).
rust_for() {
    local triple=$1
    rust_env=()
    build_std=()
    if [ "${BACKLASH_DIST_RUST:-}" != debian ] && command -v rustup >/dev/null &&
        { rustup target list --installed | grep -qx "$triple" || rustup target add "$triple" >/dev/null 2>&1; }; then
        return
    fi
    bash scripts/apt_install.sh rustc-web cargo-web rust-web-src
    echo "   $triple: rustup has no standard library for it here; Debian's rustc-web builds one (-Zbuild-std)"
    rust_env=(PATH="/usr/bin:$venv_bin:$PATH" CARGO=/usr/bin/cargo RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1)
    build_std=(-Zbuild-std=std,panic_unwind)
}

# The FMU-only library, as build.rs builds it (build/package.rs), for another target, into the same folder as
# build.rs's own build. BACKLASH_FMU_NESTED tells build.rs that this is that build (no packaging inside it).
lib_args=(--profile fmu --lib --no-default-features --target-dir target/fmu-build)

say "x86_64 Linux: cargo build --release (the FMUs of target/fmu and target/fmu3)"
BACKLASH_FMU_PORTABLE=require cargo build --release

say "x86_64 Windows: x86_64-pc-windows-gnu"
rust_for x86_64-pc-windows-gnu
env BACKLASH_FMU_NESTED=1 "${rust_env[@]}" CARGO_TARGET_X86_64_PC_WINDOWS_GNU_LINKER=x86_64-w64-mingw32-gcc \
    cargo build "${lib_args[@]}" --target x86_64-pc-windows-gnu "${build_std[@]}"
win=target/fmu-build/x86_64-pc-windows-gnu/fmu/backlash.dll

say "aarch64 Linux: aarch64-unknown-linux-gnu.2.17"
rust_for aarch64-unknown-linux-gnu
env BACKLASH_FMU_NESTED=1 PATH="$venv_bin:$PATH" "${rust_env[@]}" \
    "$venv_bin/cargo-zigbuild" zigbuild "${lib_args[@]}" --target aarch64-unknown-linux-gnu.2.17 "${build_std[@]}"
arm=target/fmu-build/aarch64-unknown-linux-gnu/fmu/libbacklash.so

# macOS: zig's own Mach-O linker ignores -exported_symbols_list (the dylib would export every Rust symbol) and
# does not sign; rust-lld does both. Apple's standard library for Rust comes only from rustup.
say "macOS: x86_64-apple-darwin, aarch64-apple-darwin (rust-lld)"
.venv/bin/python scripts/macos_sdk_stub.py target/macos-sdk
lld="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin/rust-lld"
for triple in x86_64-apple-darwin aarch64-apple-darwin; do
    command -v rustup >/dev/null && { rustup target list --installed | grep -qx "$triple" || rustup target add "$triple"; } ||
        { echo "dist: $triple needs rustup's standard library for it (rustup target add $triple)" >&2; exit 1; }
    linker_var="CARGO_TARGET_$(echo "$triple" | tr a-z- A-Z_)_LINKER"
    env BACKLASH_FMU_NESTED=1 SDKROOT="$PWD/target/macos-sdk" "$linker_var=$lld" \
        cargo rustc "${lib_args[@]}" --target "$triple" -- -C linker-flavor=ld64.lld \
        -C link-arg=-install_name -C link-arg=@rpath/libbacklash.dylib
done
mac_x86=target/fmu-build/x86_64-apple-darwin/fmu/libbacklash.dylib
mac_arm=target/fmu-build/aarch64-apple-darwin/fmu/libbacklash.dylib

say "merge into target/dist"
rm -rf target/dist
for model in BacklashPlant MrgiaEstimator; do
    .venv/bin/python scripts/merge_fmus.py "target/dist/fmi2/$model.fmu" "target/fmu/$model.fmu" \
        --binary "win64=$win" --binary "darwin64=$mac_x86"
    .venv/bin/python scripts/merge_fmus.py "target/dist/fmi3/$model.fmu" "target/fmu3/$model.fmu" \
        --binary "x86_64-windows=$win" --binary "aarch64-linux=$arm" \
        --binary "x86_64-darwin=$mac_x86" --binary "aarch64-darwin=$mac_arm"
done
say "done"
