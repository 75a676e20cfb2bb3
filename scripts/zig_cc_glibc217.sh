#!/bin/sh
# The linker of the Python extension in the manylinux2014 wheel (scripts/build_wheel.sh passes it to rustc for the
# extension's crate alone): zig's C compiler, through cargo-zigbuild's argument filter, linking against the
# symbols of GLIBC 2.17. Needs cargo-zigbuild and zig (scripts/setup.sh puts them in .venv/bin) on PATH.
exec cargo-zigbuild zig cc -- -target x86_64-linux-gnu.2.17 "$@"
