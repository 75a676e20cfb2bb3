"""The release FMUs of scripts/dist.sh, read as files: platforms, FMPy validation, and each binary's links.

- Each FMU carries exactly the platforms CONTRACT.md promises, one binary per platform, the same shared library
  in both models, and passes `fmpy.validation.validate_fmu`.
- The Windows DLL imports only DLLs every Windows (10 and later) has: no libgcc_s, libwinpthread or other
  mingw runtime beside it. Its import table is read with x86_64-w64-mingw32-objdump.
- The Linux binaries need no GLIBC symbol newer than 2.17, carry no debug information and no symbol table.
- Every platform exports the same fmi2*/fmi3* functions, and the macOS dylibs nothing else.
- The macOS dylibs (built and checked here, never loaded: no macOS at hand) are Mach-O for their processor, load
  only libSystem, need macOS 10.12 (x86_64) or 11 (arm64) and carry no debug information; the arm64 one has an
  ad-hoc code signature whose page hashes match the file (macOS on Apple silicon loads nothing unsigned).
"""
import re
import sys
import zipfile

import pytest
from elftools.elf.elffile import ELFFile
from elftools.elf.gnuversions import GNUVerNeedSection

from dist_fmus import ROOT, dist_fmu
from macho import CS_ADHOC, CS_HASHTYPE_SHA256, MH_DYLIB, MachO

sys.path.insert(0, str(ROOT / "scripts"))
from windows_binary import debug_sections, foreign_imports, pe_imports  # noqa: E402  (scripts/ is not a package)

MODELS = ["BacklashPlant", "MrgiaEstimator", "BacklashCompensator"]
PLATFORMS = {2: ["darwin64", "linux64", "win64"],
             3: ["aarch64-darwin", "aarch64-linux", "x86_64-darwin", "x86_64-linux", "x86_64-windows"]}
MACOS = {"x86_64-darwin": ("x86_64", (10, 12)), "aarch64-darwin": ("arm64", (11, 0))}  # processor, oldest macOS



def binaries(version, model):
    """{platform folder: bytes} of the FMU's binaries."""
    with zipfile.ZipFile(dist_fmu(version, model)) as z:
        return {n.split("/")[1]: z.read(n) for n in z.namelist() if n.startswith("binaries/") and not n.endswith("/")}


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("model", MODELS)
def test_platforms_and_validation(version, model):
    from fmpy.validation import validate_fmu

    bins = binaries(version, model)
    assert sorted(bins) == PLATFORMS[version]
    assert bins == binaries(version, MODELS[0]), "both models carry the same shared library"
    if version == 2:
        assert bins["darwin64"] == binaries(3, model)["x86_64-darwin"], "FMI 2.0's darwin64 is the x86_64 dylib"
    assert validate_fmu(str(dist_fmu(version, model))) == []


@pytest.fixture(scope="module")
def libs(tmp_path_factory):
    """The FMI 3.0 plant's binaries, written out: {platform: path}."""
    out = tmp_path_factory.mktemp("dist-binaries")
    paths = {}
    for folder, data in binaries(3, "BacklashPlant").items():
        p = out / folder
        p.write_bytes(data)
        paths[folder] = p
    return paths


def test_windows_dll_imports_only_what_every_windows_has(libs):
    dump, dlls = pe_imports(libs["x86_64-windows"])
    assert "kernel32.dll" in dlls, dump[:3000]
    foreign = foreign_imports(dlls)
    assert not foreign, f"the DLL needs {sorted(foreign)}, which Windows does not have"


def test_windows_dll_has_no_debug_information(libs):
    assert debug_sections(libs["x86_64-windows"]) == []


@pytest.mark.parametrize("platform", ["x86_64-linux", "aarch64-linux"])
def test_linux_binaries_need_glibc_2_17_and_carry_no_debug_information(libs, platform):
    with open(libs[platform], "rb") as f:
        elf = ELFFile(f)
        assert elf["e_machine"] == {"x86_64-linux": "EM_X86_64", "aarch64-linux": "EM_AARCH64"}[platform]
        names = [s.name for s in elf.iter_sections()]
        assert not [n for n in names if n.startswith(".debug_") or n == ".symtab"], names
        versions = set()
        for sec in elf.iter_sections():
            if isinstance(sec, GNUVerNeedSection):
                for _, auxes in sec.iter_versions():
                    versions |= {a.name for a in auxes if a.name.startswith("GLIBC_")}
    newest = max(tuple(int(x) for x in v[6:].split(".")) for v in versions)
    assert newest <= (2, 17), f"{platform} needs GLIBC {'.'.join(map(str, newest))}"


def elf_exports(path):
    with open(path, "rb") as f:
        dynsym = ELFFile(f).get_section_by_name(".dynsym")
        return {s.name for s in dynsym.iter_symbols() if s.name.startswith("fmi") and s["st_shndx"] != "SHN_UNDEF"}


def test_every_platform_exports_the_same_fmi_functions(libs):
    linux = elf_exports(libs["x86_64-linux"])
    assert any(n.startswith("fmi2") for n in linux) and any(n.startswith("fmi3") for n in linux)
    assert elf_exports(libs["aarch64-linux"]) == linux
    dump, _ = pe_imports(libs["x86_64-windows"])
    table = dump.split("[Ordinal/Name Pointer] Table", 1)[1]
    windows = set(re.findall(r"\]\s+(fmi\w+)", table))
    assert windows == linux
    for platform in MACOS:
        exports = MachO(libs[platform].read_bytes()).exports()
        assert {name.removeprefix("_") for name in exports} == linux, platform  # C names take a '_' on Mach-O


@pytest.mark.parametrize("platform", list(MACOS))
def test_macos_dylibs_are_mach_o_for_their_processor_and_load_only_libsystem(libs, platform):
    dylib = MachO(libs[platform].read_bytes())
    arch, oldest_macos = MACOS[platform]
    assert (dylib.arch, dylib.filetype) == (arch, MH_DYLIB)
    assert dylib.dylibs() == ["/usr/lib/libSystem.B.dylib"]
    assert dylib.min_macos() <= oldest_macos
    assert "__DWARF" not in dylib.segments(), dylib.segments()


def test_arm64_dylib_is_signed_ad_hoc_with_the_hashes_of_its_pages(libs):
    data = libs["aarch64-darwin"].read_bytes()
    flags, hash_type, pages, differing = MachO(data).code_signature()
    assert flags & CS_ADHOC and hash_type == CS_HASHTYPE_SHA256
    assert pages > 0 and differing == 0, f"{differing} of {pages} pages differ from their hashes"
    changed = bytearray(data)
    changed[3 * 4096 + 5] ^= 1
    assert MachO(bytes(changed)).code_signature()[3] == 1, "a changed byte is seen"
