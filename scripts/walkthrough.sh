#!/usr/bin/env bash
# The diagnosis walk-through (docs/walkthrough/README.md): runs `backlash diagnose --report` on two measured
# records and writes each report (report.md, its PNG figures) and the JSON answer beside it, so that every
# figure and number of the walk-through can be regenerated:
#
#     bash scripts/walkthrough.sh            # uses target/release/backlash, building it when missing
#     BACKLASH=path/to/backlash bash scripts/walkthrough.sh
#
# kocaeli: the friction damper with play under the Kocaeli earthquake history (brfd), validated on the
# Imperial Valley history; dc_generator: the DC motor/generator record (dc_generator), where the loop
# adds several effects one after another. The records are found by scripts/data_records.py (data/, or
# BACKLASH_DATA); `python3 scripts/fetch_data.py` puts them there.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${BACKLASH:-target/release/backlash}
if [ ! -x "$bin" ]; then
    BACKLASH_FMU=never cargo build --release --bin backlash
fi
out=docs/walkthrough

# One report: name, then the arguments of `backlash diagnose` (the report folder and --json are added).
report() {
    local name=$1
    shift
    rm -rf "${out:?}/$name"
    "$bin" diagnose "$@" --report "$out/$name" --json >"$out/$name.json"
    echo "$out/$name/report.md"
}

record() { python3 scripts/data_records.py "$1"; }
kocaeli=$(record brfd/KocaeliDBE_36lb.csv)
imperial=$(record brfd/ImperialValleyDBE_36lb.csv)
generator=$(record dc_generator/dc_generator.csv)
report kocaeli "$kocaeli" --time-col t --decimate 16 --validate-on "$imperial"
report dc_generator "$generator" --decimate 5
