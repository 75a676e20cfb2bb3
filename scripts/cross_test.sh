#!/usr/bin/env bash
# The FMUs on every platform they ship for: `bash scripts/dist.sh` (target/dist), then tests/cross:
# test_dist.py reads the FMUs (platforms, fmpy validation, the Windows DLL's import table, GLIBC 2.17, no debug
# information, the same exports everywhere); test_cross.py runs one C master natively, under Wine (the Windows
# DLL) and under qemu-aarch64 (the aarch64 library) on paper 000's example in FMI 2.0 and 3.0;
# test_fmpy_remoting.py runs FMPy's Wine remoting on the DLL. Installs Wine, QEMU and the arm64 C library
# (Debian packages) when missing. `--no-dist`: test the target/dist that an earlier `bash scripts/dist.sh` left
# (scripts/test.sh runs dist.sh right after its release build; see there why).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/apt_install.sh gcc wine64 qemu-user-static libc6-arm64-cross libgcc-s1-arm64-cross
if [ "${1:-}" = --no-dist ]; then
    [ -d target/dist ] || { echo "cross_test: --no-dist, but target/dist is missing (bash scripts/dist.sh)" >&2; exit 1; }
else
    bash scripts/dist.sh
fi
.venv/bin/python -m pip install -q --disable-pip-version-check -c tests/python/requirements.txt numpy fmpy pytest
.venv/bin/python -m pytest -q -p no:cacheprovider tests/cross
