#!/usr/bin/env python3
"""Put every measured record the project uses into data/ and check its sha256.

The records are not part of the repository. Each data/<folder>/README.md gives the source, licence,
conversion and sha256 of its files; this script reads the hashes there (scripts/data_records.py).

    python3 scripts/fetch_data.py --from DIR   # copy from a folder with the same layout (folder/file.csv)
    python3 scripts/fetch_data.py              # download each source at its pinned commit and convert it
                                               # (scripts/convert_records.py); needs internet access
    python3 scripts/fetch_data.py --extra      # the same, and the optional set too (the rows marked `extra`
                                               # in data/*/README.md; neither the tests nor CI need them)
    python3 scripts/fetch_data.py --survey     # the survey set only (the rows marked `survey`: records of
                                               # other systems for scripts/verdict_survey.py); with --extra
                                               # too, all three sets; --from DIR copies them likewise

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


# The survey set's sources (`--survey`; each folder's README names them and their licence).
NLID = ("Rafa7046/Non_Linear_Identification", "e5c9b006b0a2ec1650bc018a5fb38d2f4363d4c7")
DRYER = ("danielsmorais/system-identification", "66496651a4042e2e7ec864a9c797ae4263400117")
FURNACE = ("datasets/datapackage-factory-openMV", "116ab52a4f0e52f9621cfac42ada2c417d82adb3")
F16 = ("forgi86/dynonet", "0bdf70605da2570cca526659b3b21e6356e7bb48")  # the data are gone from later commits
KEIEL = ("gkeiel/dc_motor_position_control", "b9a466d784daeb843fc443622c84e7f49c0a136f")
HSM150 = ("malik-robert/HSM150-data", "35c3b1be8a4c2215ff981eb00bb3ed439e9f524b")
LPV = ("gsmfnc/LPV_SysId", "a843d61efb1401308c932bd77b6653446bbdd351")
LPV_WH = ("gsmfnc/LPV_SysId", "06c5f77ff16153e37e17e671f77db0c17864a0e1")  # wh.mat's unshifted copy
KUKA = ("JonasWeigand/Robot_Identification", "9e403c07d9dadbb391a9f3921e8d219f714636a8")
KUKA_MAT = {  # trajectory -> sha256 of its data.mat
    "A": "4c152c5b7f2c899731fdeebcf0d011cc103df72be19fac160caf47aa9b73ab75",
    "B": "edeb35f65c4ec4bb697e757fc1e4e9668551b6fe7b2c3dbbb526d040dd8d5ce7",
    "C": "c5d5688521ece941e6c4afd39643a01cd36ae8c7790342640277f8b15b5515b4",
}


def table(repo: tuple[str, str], path: str, sha256: str, u: str | int, y: str | int, dt: float) -> Recipe:
    """Two columns of a numeric table, t = k * dt (convert_records.convert_table)."""
    return Recipe((Source(*repo, path, sha256),), lambda s, out: convert_records.convert_table(s[0], u, y, dt, out))


def mat(repo: tuple[str, str], path: str, sha256: str, u: str, y: str, dt: float | None = None,
        time: str | None = None) -> Recipe:
    """Two series of a MAT-file, t = k * dt or from the series `time` (convert_records.convert_mat)."""
    return Recipe((Source(*repo, path, sha256),),
                  lambda s, out: convert_records.convert_mat(s[0], u, y, out, dt=dt, time=time))


def kuka(trajectory: str, axis: int) -> Recipe:
    """One axis of a KUKA KR300 trajectory: motor-side position to link-side (secondary encoder) position."""
    path = f"data/recorded_trajectories/2020-10-21 10s FF {trajectory} 08ms/data.mat"
    return mat(KUKA, path, KUKA_MAT[trajectory], f"rec.act_pos_mot_deg({axis},:)", f"rec.act_pos_se_deg({axis},:)",
               time="rec.time_cont")


def servo_survey(log: str, sha256: str, motor: int) -> Recipe:
    return Recipe((Source(*SERVO, f"logs/{log}", sha256),),
                  lambda s, out: convert_records.convert_servo(s[0], motor, out, spelling="t"))


def f16(name: str, sha256: str) -> Recipe:
    """The shaker's force to the acceleration at the excitation point (row 1 of Acceleration), Fs = 400 Hz."""
    return mat(F16, f"examples/F16GVT/data/BenchmarkData/{name}.mat", sha256, "Force", "Acceleration(1,:)",
               dt=1 / 400)


def keiel(folder: str, sha256: str) -> Recipe:
    """The controller output (Channel 4) to the potentiometer angle (Channel 2), 2 ms."""
    return table(KEIEL, f"{folder}/data.csv", sha256, "Channel 4", "Channel 2", 0.002)


def hsm150(name: str, sha256: str) -> Recipe:
    """Torque (column 5 of `data`) to velocity (column 4); column 1 is the time."""
    return mat(HSM150, f"Data/Identification/{name}.mat", sha256, "data(:,5)", "data(:,4)", time="data(:,1)")


SURVEY_RECIPES = {
    "nonlinear_identification/silverbox_SNLS80mV.csv": table(
        NLID, "src/data/SNLS80mV.csv", "ae62d5a91230c10f76e6dd02c8a4fac3c9d4d8a95fbf50e87cb0c4885003e0f1",
        "V1", "V2", 1 / 610.3515625),
    "nonlinear_identification/daisy_ballbeam.csv": table(
        NLID, "src/data/ball-and-beam.csv", "07c1ba1f2facdf8045a49d368a99f01e3ff261b12acb1fe3c934917bc2753170",
        "u", "y", 0.1),
    "nonlinear_identification/daisy_exchanger.csv": table(
        NLID, "src/data/exchanger.csv", "3dfbb1e1c2f789a3593b460373c5c0a649647ab5548478ed0992c68d5b2c5f34",
        "q", "th", 1.0),
    "nonlinear_identification/daisy_flexible_robot_arm.csv": table(
        NLID, "src/data/robot-arm.csv", "781d988c06d8f6c120985d135a204d290ee7e4f1f4067ad3f3338851b6202cf7",
        "u", "y", 1.0),
    "hair_dryer/daisy_hair_dryer.csv": table(
        DRYER, "Projeto_1/secador/dryer.dat", "81569d0ae3684fa30df8e7b54aa48518e92ce4a849bd5e8a7559d55422492308",
        0, 1, 1.0),
    "gas_furnace/boxjenkins_gas_furnace_seriesJ.csv": table(
        FURNACE, "gas-furnace/data/gas-furnace.csv",
        "ce46e11490a11ac254a959d42d5858f66b3c8013a1b667e553b3d890c67e4d43", "InputGasRate", "CO2", 9.0),
    "f16gvt/f16gvt_sinesweep_level1.csv": f16(
        "F16Data_SineSw_Level1", "cf3554012b2fb2bfc8f8f1f5c678ccb2a23512466b0f4fbb3d6e2c4b5b2215ac"),
    "f16gvt/f16gvt_fullmsine_level1.csv": f16(
        "F16Data_FullMSine_Level1", "30e7bec7115a117f1391466c1dce34d05c673054fd1a862c441bd4d45dc19b2b"),
    "f16gvt/f16gvt_sinesweep_level7.csv": f16(
        "F16Data_SineSw_Level7", "54415f357a6a057dc1dd73a030b6105f1a1efa801a4abb05cfe8678facc87c6f"),
    "dc_motor_keiel/dcmotor_keiel_relay.csv": keiel(
        "dc_motor_relay_method", "afa52e515cd790998c39aeaa1cf624e492950874a62b656823da141fad58d088"),
    "dc_motor_keiel/dcmotor_keiel_pid_sine.csv": keiel(
        "dc_motor_position_control_pid", "ecf6893acbd7ee7449ce23a417291a4983d2b41449f015575315025ab3328548"),
    "dc_motor_keiel/dcmotor_keiel_pid_step.csv": keiel(
        "dc_motor_position_control_pid_step", "818baef275185ab78a8abdbae1b93691b11aceca3c37c25c494e81f04fdde79e"),
    "hsm150/hsm150_idf_pos_0.06_1.csv": hsm150(
        "idf_pos_0.06_1", "c9474de666dd99c65dbda3e00be5ef0b517b4a72c675822efc3281f828da3dd6"),
    "hsm150/hsm150_idf_neg_0.04_1.csv": hsm150(
        "idf_neg_0.04_1", "2fae3c385bef58e1fd8b8e7959e4bc8e921decb1e2937713b5066ec52128f1e4"),
    "lpv_sysid/matlab_robotarm_wernholt_estimation.csv": mat(
        LPV, "noise_simulations/autoencoders/RobotArm.mat",
        "e1b3699b2ecf8dec54b33badb3a63160a6ce7c8cbf84e1616575b7901d688421", "U", "Y", dt=5e-4),
    "lpv_sysid/matlab_mrdamper_estimation.csv": mat(
        LPV, "noise_simulations/autoencoders/Magneto.mat",
        "a9e82d26466be6fe55397ab4d6945f8479d9e3fb63b6d92839c0d841149a1e07", "U", "Y", dt=1.0),
    "lpv_sysid/wiener_hammerstein_2009_estimation_slice.csv": mat(
        LPV_WH, "autoencoders/datasets/wh.mat", "025a3b6059b968c83f8a2ee2a42802f4d81bc13d86c3c88203f179ec862bef7e",
        "U", "Y", dt=1 / 51200),
    "brfd_survey/brfd_ds2_1Hz30lb_1in.csv": brfd(
        "characterization datasets/1Hz30lbtension1amplitude.json",
        sha256="ed02a98a96369937851bed92b4e5e92e34d98ceebd4db81d5bd65d5b77c4bc91"),
    "brfd_survey/brfd_ds1_1Hz35lb.csv": brfd(
        "characterization datasets/1Hz35lbtension.json", dataset="dataset-1",
        sha256="7f9c9e25e8747d89c3fc09be883fb010352b0916d5e50a2d6cb834c2904af394"),
    "kuka_kr300/kuka_kr300_weigand_trajA_axis1_motorpos_to_linkpos.csv": kuka("A", 1),
    "kuka_kr300/kuka_kr300_weigand_trajA_axis2_motorpos_to_linkpos.csv": kuka("A", 2),
    "kuka_kr300/kuka_kr300_weigand_trajA_axis3_motorpos_to_linkpos.csv": kuka("A", 3),
    "kuka_kr300/kuka_kr300_weigand_trajB_axis1_motorpos_to_linkpos.csv": kuka("B", 1),
    "kuka_kr300/kuka_kr300_weigand_trajC_axis1_motorpos_to_linkpos.csv": kuka("C", 1),
    "servo_survey/servo_sts3215_nocomp2_m1.csv": servo_survey(
        "motor_telemetry_nocomp2.csv", "11c62dcdcc1550ad4a495fe533b566d5e5f34323e3f074199442cd817ed8eafd", 1),
    "servo_survey/servo_sts3215_comp2_m1.csv": servo_survey(
        "motor_telemetry_comp2.csv", "eca1e69d17376979462e6a208fa649cc4906a82d6efd7d63456cf82166d2eb21", 1),
    "servo_survey/servo_sts3215_pgain_zero_db_m1.csv": servo_survey(
        "motor_telemetry_pgain_zero_db.csv", "75c484654bbe4b9f767bc10a8d84639c49a16150209c23991434440611956df8", 1),
}


# Every record of data/*/README.md, of the default, the optional and the survey set, with its recipe (the READMEs say
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
    # The survey set (`--survey`): the rows marked `survey` in data/*/README.md.
    **SURVEY_RECIPES,
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


def chosen_sets(default: dict[str, str], optional: dict[str, str], survey: dict[str, str], extra: bool,
                with_survey: bool) -> dict[str, str]:
    """The records a run without names puts in place: the default set, unless --survey comes alone; the
    optional set with --extra; the survey set with --survey."""
    chosen = {} if with_survey and not extra else dict(default)
    if extra:
        chosen.update(optional)
    if with_survey:
        chosen.update(survey)
    return chosen


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--from", dest="from_dir", metavar="DIR", type=pathlib.Path,
                   help="copy the records from DIR (same layout as data/) instead of downloading them")
    p.add_argument("--to", metavar="DIR", type=pathlib.Path, default=None,
                   help=f"where to put them (default: ${data_records.DATA_ENV} when set, otherwise data/)")
    p.add_argument("--extra", action="store_true",
                   help="also the optional set (the rows marked `extra` in data/*/README.md)")
    p.add_argument("--survey", action="store_true",
                   help="the survey set (the rows marked `survey` in data/*/README.md): alone, or with --extra "
                   "beside the default and optional sets")
    p.add_argument("records", nargs="*", metavar="NAME",
                   help="only these records (as folder/file.csv, of any set; default: the default set of "
                   "data/*/README.md, and the optional set with --extra; the survey set with --survey)")
    a = p.parse_args(argv)
    default, optional = data_records.manifest(), data_records.manifest(extra=True)
    survey = data_records.manifest(survey=True)
    known = {**default, **optional, **survey}
    unknown = [n for n in a.records if n not in known]
    if unknown:
        p.error(f"unknown record {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    if a.from_dir is not None and not a.from_dir.is_dir():
        p.error(f"--from {a.from_dir}: no such folder")
    chosen = {n: known[n] for n in (a.records or chosen_sets(default, optional, survey, a.extra, a.survey))}
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
