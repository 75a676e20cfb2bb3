#!/usr/bin/env bash
# The main job on a fresh machine: set up, build both FMUs and the CLI, co-simulate plant + estimator on
# paper 000's example, print how the estimates converge, and write the plots to out/. One release build of the
# crate; the Python package's extension is compiled on top of it (no wheel: that is CI's job).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --main
cargo build --release
bash scripts/install_package.sh
.venv/bin/python scripts/paper_cosim.py "$@"
