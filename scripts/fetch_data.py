#!/usr/bin/env python3
"""Put every measured record the project uses into data/ and check its sha256.

The records are not part of the repository. Each data/<folder>/README.md gives the source, licence,
conversion and sha256 of its files; this script reads the hashes there (scripts/data_records.py).

    python3 scripts/fetch_data.py --from DIR   # copy from a folder with the same layout (folder/file.csv)
    python3 scripts/fetch_data.py              # download each source at its pinned commit and convert it
                                               # (scripts/convert_records.py); needs internet access
    python3 scripts/fetch_data.py --extra      # the same, and the optional set too (the rows marked `extra`
                                               # in data/*/README.md; neither the tests nor CI need them)

A record already in place with the right sha256 is kept (a second run only reads and checks every file). A
file is written under a temporary name beside its destination and renamed once its sha256 is right: a wrong
hash, a failed copy or a failed download leaves no half-written file, and the error names the file and both
hashes. Every record is tried; the exit status is 1 when any failed. Only the standard library is used.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import os
import pathlib
import shutil
import sys
import tempfile
import time
import urllib.parse
import urllib.request
from collections.abc import Callable

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import convert_records  # noqa: E402 - the sibling scripts, found through the line above
import data_records  # noqa: E402

DOWNLOAD_TIMEOUT = 120.0  # seconds for one source file


@dataclasses.dataclass(frozen=True)
class Source:
    """One file of a public repository at a pinned commit; sha256 when its README gives it."""

    repo: str
    commit: str
    path: str
    sha256: str = ""

    def url(self) -> str:
        return f"https://raw.githubusercontent.com/{self.repo}/{self.commit}/{urllib.parse.quote(self.path)}"


@dataclasses.dataclass(frozen=True)
class Recipe:
    """How one record is made from its sources: convert(source files, output file)."""

    sources: tuple[Source, ...]
    convert: Callable[[list[str], str], int]


BRFD = ("ARTS-Laboratory/Dataset-Friction-Damper-with-Backlash", "0e09aa9d950760277e31c08cd93fd01f39a5af09")
GENERATOR = ("wilsonrljr/sysidentpy-data", "72715362eadcf860fdbd77d88b5d7e92b6143a83")
TANKS = (
    "MiladBnit/Uncertainty-quantification-in-neural-state-space-models-applications",
    "2a565d57ca30bdf126da507c00ad1f1e481ca434",
)
SERVO = ("roboninecom/Measuring-Backlash-in-Popular-UART-Servos", "8ffad86cc674df20eb0c17ecd18f8b317a127a17")
EMPS = ("forgi86/sysid-neural-continuous", "956aa7ecd73061b0321c6f6098d74c9e4a7ce67a")
TANKS_SOURCE = Source(
    *TANKS, "dataBenchmark.csv", "7416cb2aeb97c0775f2d9fdd4be698024d49608f8b0a8e767755c5ecb2bb023c"
)


def brfd(path: str, dataset: str = "dataset-2", sha256: str = "") -> Recipe:
    return Recipe((Source(*BRFD, f"data/{dataset}/{path}", sha256),),
                  lambda s, out: convert_records.convert_brfd(s[0], out))


def servo(log: str, motor: int) -> Recipe:
    return Recipe((Source(*SERVO, f"logs/{log}"),), lambda s, out: convert_records.convert_servo(s[0], motor, out))


def tanks(part: str) -> Recipe:
    return Recipe((TANKS_SOURCE,), lambda s, out: convert_records.convert_tanks(s[0], part, out))


# Every record of data/*/README.md, of the default and the optional set, with its recipe (the READMEs say
# the same in words).
RECIPES = {
    "brfd/char_0.5Hz_36lb_1in.csv": brfd("characterization datasets/0.5Hz36lbtension1amplitude.json"),
    "brfd/KocaeliDBE_36lb.csv": brfd("earthquake profiles/KocaeliDBE.json"),
    "brfd/ImperialValleyDBE_36lb.csv": brfd("earthquake profiles/ImperialValleyDBE.json"),
    "dc_generator/dc_generator.csv": Recipe(
        (
            Source(*GENERATOR, "datasets/generator/x_cc.csv",
                   "673e1550f82f83f73d7370fba29d2fdf117740dea27832567efa80bd86417fae"),
            Source(*GENERATOR, "datasets/generator/y_cc.csv",
                   "45f87a54ccb1a478a5f813e9adf80240844ce5a23a9e5a983850fbbcdceaafb5"),
        ),
        lambda s, out: convert_records.convert_generator(s[0], s[1], out),
    ),
    "tanks/tanks_est.csv": tanks("Est"),
    "tanks/tanks_val.csv": tanks("Val"),
    "servo/sts3215_hold.csv": servo("motor_telemetry_single.csv", 5),
    "servo/sts3250_hold.csv": servo("motor_telemetry_single_3250.csv", 4),
    "emps/emps.csv": Recipe(
        (Source(*EMPS, "examples/EMPS/data/DATA_EMPS.mat",
                "6cf6814ae14618795da0101aae2bb97ff0c6351b0501b5492751b02b07facf7e"),),
        lambda s, out: convert_records.convert_emps(s[0], out),
    ),
    # The optional set (`--extra`): six more tests of the damper, data/brfd/README.md's second table.
    "brfd/char_1Hz_36lb_1in.csv": brfd(
        "characterization datasets/1Hz36lbtension1amplitude.json",
        sha256="e710058c4885fe151a4d8d3370586d4614e3626e62eb7455029ad5e8a2320740"),
    "brfd/char_0.25Hz_30lb_0.5in.csv": brfd(
        "characterization datasets/0.25Hz30lbtension0.5amplitude.json",
        sha256="e3e83b088431c2027ca6b3c11f3be015dac67ab11bfa4293556184e852c74b34"),
    "brfd/char_0.5Hz_0lb_1.5in.csv": brfd(
        "characterization datasets/0.5Hz0lbtension1.5amplitude.json",
        sha256="d86fe4103505a3249e523a6caa133559a4da93d53dda5094b700fb0b14045913"),
    "brfd/char_2Hz_36lb_0.5in.csv": brfd(
        "characterization datasets/2Hz36lbtension0.5amplitude.json",
        sha256="30db5d48cbf6eed80e2838e5185a0b26eb9108aac64fc2dcdf0e2dcbedd7c4be"),
    "brfd/KocaeliMCE_36lb.csv": brfd(
        "earthquake profiles/KocaeliMCE.json",
        sha256="029d9b68385ff3a6a62b7728e1307b46b4f78601cdb92716f3c2aab00de552bc"),
    "brfd/d1_char_0.5Hz_35lb.csv": brfd(
        "characterization datasets/0.5Hz35lbtension.json", dataset="dataset-1",
        sha256="15372efa141b1cf8ba7e8166bc37f51084f2f2ab76b466df4ee93f999fcbb5c2"),
}


class FetchError(Exception):
    """One record could not be put in place (the message names it)."""


def sha256_of(path: pathlib.Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def temp_beside(dest: pathlib.Path) -> pathlib.Path:
    """A new empty file in dest's folder (created if needed), to be renamed onto dest."""
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".part", dir=dest.parent)
    os.close(fd)
    return pathlib.Path(name)


def install(name: str, want: str, dest: pathlib.Path, fill: Callable[[pathlib.Path], str]) -> str:
    """fill(temporary file) writes the record and says where from; the file becomes dest only if its sha256
    is `want`. The temporary file is removed on every failure."""
    tmp = temp_beside(dest)
    try:
        origin = fill(tmp)
        got = sha256_of(tmp)
        if got != want:
            raise FetchError(
                f"{name}: the file made from {origin} has sha256 {got}, but data/{name.split('/')[0]}/README.md "
                f"gives {want}; nothing written"
            )
        os.chmod(tmp, 0o666 & ~current_umask())  # mkstemp made it private; the record is not
        os.replace(tmp, dest)
        return origin
    finally:
        tmp.unlink(missing_ok=True)


def current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def copier(src_dir: pathlib.Path, name: str) -> Callable[[pathlib.Path], str]:
    def fill(tmp: pathlib.Path) -> str:
        src = src_dir / name
        if not src.is_file():
            raise FetchError(f"{name}: not in {src_dir} (looked for {src})")
        shutil.copyfile(src, tmp)
        return str(src)

    return fill


def download(source: Source, to: pathlib.Path) -> None:
    """One source file, its sha256 checked when known (a partial download fails that check or the read)."""
    url = source.url()
    try:
        with urllib.request.urlopen(url, timeout=DOWNLOAD_TIMEOUT) as r, open(to, "wb") as f:
            shutil.copyfileobj(r, f)
    except OSError as e:  # URLError and HTTPError are OSErrors
        raise FetchError(f"{source.path} of {source.repo} at {source.commit[:12]}: cannot download {url}: {e}") \
            from e
    if source.sha256:
        got = sha256_of(to)
        if got != source.sha256:
            raise FetchError(
                f"{source.path} of {source.repo} at {source.commit[:12]}: downloaded file has sha256 {got}, "
                f"expected {source.sha256}"
            )


def converter(name: str, cache: dict[Source, pathlib.Path], work: pathlib.Path) -> Callable[[pathlib.Path], str]:
    """Download the record's sources (once per run: two records may share one) and convert them."""
    recipe = RECIPES.get(name)
    if recipe is None:
        raise FetchError(f"{name}: no download recipe in scripts/fetch_data.py; use --from DIR")

    def fill(tmp: pathlib.Path) -> str:
        paths = []
        for source in recipe.sources:
            if source not in cache:
                local = work / f"{len(cache)}-{pathlib.PurePosixPath(source.path).name}"
                print(f"    downloading {source.url()}", flush=True)
                download(source, local)
                cache[source] = local
            paths.append(str(cache[source]))
        recipe.convert(paths, str(tmp))
        return ", ".join(f"{s.repo}@{s.commit[:12]}:{s.path}" for s in recipe.sources)

    return fill


def fetch(records: dict[str, str], dest_dir: pathlib.Path, from_dir: pathlib.Path | None) -> list[str]:
    """Put every record in place; the list of errors (empty when all are in place with the right hash)."""
    errors = []
    cache: dict[Source, pathlib.Path] = {}
    with tempfile.TemporaryDirectory(prefix="backlash-fetch-") as work:
        for i, (name, want) in enumerate(sorted(records.items()), 1):
            dest = dest_dir / name
            t0 = time.monotonic()
            prefix = f"[{i}/{len(records)}] {name}:"
            try:
                if dest.is_file() and sha256_of(dest) == want:
                    print(f"{prefix} in place, sha256 {want[:12]} ok", flush=True)
                    continue
                stale = " (replacing a file with another sha256)" if dest.exists() else ""
                fill = copier(from_dir, name) if from_dir else converter(name, cache, pathlib.Path(work))
                origin = install(name, want, dest, fill)
                print(f"{prefix} from {origin}{stale}, sha256 {want[:12]} ok "
                      f"({time.monotonic() - t0:.1f} s)", flush=True)
            except (FetchError, OSError, ValueError, SystemExit) as e:
                why = str(e) if str(e).startswith(name) else f"{name}: {e}"
                print(f"{prefix} FAILED: {why}", flush=True)
                errors.append(why)
    return errors


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--from", dest="from_dir", metavar="DIR", type=pathlib.Path,
                   help="copy the records from DIR (same layout as data/) instead of downloading them")
    p.add_argument("--to", metavar="DIR", type=pathlib.Path, default=None,
                   help=f"where to put them (default: ${data_records.DATA_ENV} when set, otherwise data/)")
    p.add_argument("--extra", action="store_true",
                   help="also the optional set (the rows marked `extra` in data/*/README.md)")
    p.add_argument("records", nargs="*", metavar="NAME",
                   help="only these records (as folder/file.csv, of either set; default: the default set of "
                   "data/*/README.md, and the optional set with --extra)")
    a = p.parse_args(argv)
    default, optional = data_records.manifest(), data_records.manifest(extra=True)
    known = {**default, **optional}
    unknown = [n for n in a.records if n not in known]
    if unknown:
        p.error(f"unknown record {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    if a.from_dir is not None and not a.from_dir.is_dir():
        p.error(f"--from {a.from_dir}: no such folder")
    chosen = {n: known[n] for n in (a.records or (known if a.extra else default))}
    dest_dir = a.to or data_records.data_dir()
    errors = fetch(chosen, dest_dir, a.from_dir)
    if errors:
        print(f"error: {len(errors)} of {len(chosen)} records are not in {dest_dir}:", file=sys.stderr)
        for e in errors:
            print(f"  {e}", file=sys.stderr)
        return 1
    print(f"all {len(chosen)} records in {dest_dir}, every sha256 checked")
    return 0


if __name__ == "__main__":
    sys.exit(main())
