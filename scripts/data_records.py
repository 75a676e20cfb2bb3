#!/usr/bin/env python3
"""Where the measured records are: the one place the Python tests and scripts find them (the Rust side's twin
is tests/records.rs).

The records are not part of the repository: `python3 scripts/fetch_data.py` puts them into data/ (each
data/<folder>/README.md gives the source, licence, conversion and sha256 of its files); BACKLASH_DATA, when
set, names another folder with the same layout to read them from.

    python3 scripts/data_records.py brfd/KocaeliDBE_36lb.csv   # prints its path (relative to the repository
                                                               # root when inside it), or fails naming the
                                                               # fetch step

A README's hash table may mark a row `extra` in a third column: that record belongs to the optional set, which
neither the default fetch nor CI needs (`python3 scripts/fetch_data.py --extra` adds it). A row marked `survey`
belongs to the survey set: further public records of other systems, for measuring the verdict on play across
many sources (`python3 scripts/fetch_data.py --survey`; scripts/verdict_survey.py).
"""

from __future__ import annotations

import os
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA_ENV = "BACKLASH_DATA"
FETCH_COMMAND = "python3 scripts/fetch_data.py"
# A row of a README's hash table: `| file.csv | <64 hex digits> |`, or `| file.csv | <64 hex digits> | extra |`
# for a record of the optional set, `... | survey |` for one of the survey set (rows naming a source file have
# words before the file name and are not records).
HASH_ROW = re.compile(r"^\|\s*([\w.\-]+\.csv)\s*\|\s*([0-9a-f]{64})\s*\|(?:([^|]*)\|)?")
EXTRA = "extra"  # the third cell that puts a record into the optional set
SURVEY = "survey"  # the third cell that puts a record into the survey set


class MissingRecord(FileNotFoundError):
    """A measured record that is not where the tests read records from."""


def data_dir() -> pathlib.Path:
    """BACKLASH_DATA when set, otherwise the repository's data/."""
    env = os.environ.get(DATA_ENV)
    return pathlib.Path(env) if env else ROOT / "data"


def record_path(name: str) -> pathlib.Path:
    """The path of the record `name` (as in data/, e.g. "brfd/KocaeliDBE_36lb.csv"); MissingRecord, naming it
    and the fetch command, when it is not there."""
    folder = data_dir()
    path = folder / name
    if not path.is_file():
        raise MissingRecord(
            f"the measured record {name} is not in {folder} (looked for {path}): run `{FETCH_COMMAND}` first "
            f"(or `{FETCH_COMMAND} --from DIR` with a folder that holds the records; {DATA_ENV} names another "
            "folder to read them from)"
        )
    return path


def manifest(readmes: pathlib.Path = ROOT / "data", extra: bool = False, survey: bool = False) -> dict[str, str]:
    """The records of the default set (with extra, of the optional set; with survey, of the survey set), as
    {"folder/file.csv": sha256}, read from the hash tables of data/*/README.md (the one place the hashes are
    written). ValueError, naming the README and the row, for a third cell other than empty, `extra` or
    `survey`."""
    if extra and survey:
        raise ValueError("manifest: one set at a time (extra or survey)")
    want = SURVEY if survey else EXTRA if extra else ""
    records = {}
    for readme in sorted(readmes.glob("*/README.md")):
        for line in readme.read_text(encoding="utf-8").splitlines():
            m = HASH_ROW.match(line.strip())
            if not m:
                continue
            mark = (m.group(3) or "").strip()
            if mark not in ("", EXTRA, SURVEY):
                raise ValueError(f"{readme}: the row of {m.group(1)} is marked {mark!r}; only `{EXTRA}` (the "
                                 f"optional set), `{SURVEY}` (the survey set) or nothing (the default set) is known")
            if mark == want:
                records[f"{readme.parent.name}/{m.group(1)}"] = m.group(2)
    return records


def shown(path: pathlib.Path) -> str:
    """A path inside the repository relative to its root (the scripts that print it run there, and their
    outputs quote it), any other as it is."""
    try:
        return str(path.resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def main(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if argv else 2
    try:
        for name in argv:
            print(shown(record_path(name)))
    except MissingRecord as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
