"""A stub macOS SDK for linking the FMUs' library for macOS on Linux: usr/lib/libSystem.tbd (and libc, libm,
which on macOS are libSystem), the text stub (TAPI) of the one library it links against.

    python scripts/macos_sdk_stub.py OUT_DIR

Made from the stub that the zig package (already installed for the Linux builds) ships, with its targets
renamed for LLVM's linker (rust-lld, ld64 flavour): zig lists Apple silicon as `arm64e` and `arm64e.x1`,
rust-lld links `arm64` and knows neither. The symbols are Apple's libSystem's; nothing else of an SDK is
needed, since the library calls only the C library. Point SDKROOT at OUT_DIR for the link.
"""
import pathlib
import re
import sys

import ziglang


def stub(text):
    """zig's libSystem.tbd with its Apple silicon targets named `arm64` (the `.x1` variants dropped)."""
    text = re.sub(r",\s*arm64e\.x1-(macos|maccatalyst)", "", text)
    return text.replace("arm64e-", "arm64-")


def main(out):
    src = pathlib.Path(ziglang.__file__).parent / "lib" / "libc" / "darwin" / "libSystem.tbd"
    lib = pathlib.Path(out) / "usr" / "lib"
    lib.mkdir(parents=True, exist_ok=True)
    text = stub(src.read_text())
    if "arm64-macos" not in text or "x86_64-macos" not in text:
        sys.exit(f"{src}: no arm64/x86_64 macOS targets after renaming; zig's stub has changed")
    for name in ("libSystem", "libc", "libm"):
        (lib / f"{name}.tbd").write_text(text)


if __name__ == "__main__":
    main(sys.argv[1])
