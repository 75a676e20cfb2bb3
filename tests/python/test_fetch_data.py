"""The fetch step (scripts/fetch_data.py), the records' one finder (scripts/data_records.py) and the conversions
of scripts/convert_records.py that the download path uses, on files made here."""
import hashlib
import pathlib
import struct
import urllib.parse
import zlib

import pytest

import convert_records
import data_records
import fetch_data


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


# The default set, as it was before the optional set came: what the tests, CI (from its folder, without
# internet access) and a plain `fetch_data.py` put in place.
DEFAULT_SET = {
    "brfd/char_0.5Hz_36lb_1in.csv": "a34eb31f50cadcb91556cf38ab249a3003882138013fa74d0b0536353ac42086",
    "brfd/KocaeliDBE_36lb.csv": "df8c7f63e02681afaae5f2860dbb1303104dca608c3d81c1581de34cf4c42252",
    "brfd/ImperialValleyDBE_36lb.csv": "318edb8854cce61c6f8df249811bede66f5de973351311789a7ffb5b7623b7ea",
    "dc_generator/dc_generator.csv": "99b0cce8387b53122734fbfbe4d74b018202b7f6bbd2639895325e2fc715bb6e",
    "emps/emps.csv": "e9e66e31e01c7c8e40a5cb779bdf431820515fb56c921d323f279db27b7cb2b1",
    "servo/sts3215_hold.csv": "da1cc5dc2f4c62cafde635e47a26b0c633a8e760d8b122dd688776cccc3b3aa5",
    "servo/sts3250_hold.csv": "2d234043d790f0d1adef156ef82a1059aa34ccb5081b98ef3a220769317e008c",
    "tanks/tanks_est.csv": "669ca83d33e30730ef327a6de40e85f531c7ac3a58ad863119c6a86bcf40f166",
    "tanks/tanks_val.csv": "e56903923b099158bc36b31120e1b25823ecc47afc6e0ff847d1e5b2e74bfc5e",
}
DAMPER = ("ARTS-Laboratory/Dataset-Friction-Damper-with-Backlash", "0e09aa9d950760277e31c08cd93fd01f39a5af09")


def test_the_default_set_is_the_nine_records_and_every_record_has_a_recipe():
    assert data_records.manifest() == DEFAULT_SET
    extra = data_records.manifest(extra=True)
    assert len(extra) == 6 and not set(extra) & set(DEFAULT_SET)
    assert all(len(h) == 64 for h in extra.values())
    survey = data_records.manifest(survey=True)
    assert not set(survey) & (set(DEFAULT_SET) | set(extra))
    assert set(fetch_data.RECIPES) == set(DEFAULT_SET) | set(extra) | set(survey)


def test_the_survey_sets_recipes_name_pinned_sources_with_their_hash():
    survey = data_records.manifest(survey=True)
    assert len(survey) == 27 and all(len(h) == 64 for h in survey.values())
    for name in survey:
        for source in fetch_data.RECIPES[name].sources:
            assert len(source.commit) == 40 and len(source.sha256) == 64, name
            assert source.url().startswith(f"https://raw.githubusercontent.com/{source.repo}/{source.commit}/")
            assert " " not in source.url(), name


def test_the_optional_sets_recipes_name_one_pinned_damper_file_each():
    for name in data_records.manifest(extra=True):
        (source,) = fetch_data.RECIPES[name].sources
        assert (source.repo, source.commit) == DAMPER, name
        assert source.path.startswith(("data/dataset-1/", "data/dataset-2/")) and source.path.endswith(".json")
        assert len(source.sha256) == 64 and int(source.sha256, 16) >= 0, name
        url = source.url()
        assert url.startswith(f"https://raw.githubusercontent.com/{DAMPER[0]}/{DAMPER[1]}/data/dataset-")
        assert " " not in url and urllib.parse.unquote(url).endswith(source.path)
    # Each source file appears once, and the README's source table names it beside the record.
    paths = [fetch_data.RECIPES[n].sources[0].path for n in data_records.manifest(extra=True)]
    assert len(set(paths)) == 6
    readme = (data_records.ROOT / "data" / "brfd" / "README.md").read_text()
    for name in data_records.manifest(extra=True):
        source = fetch_data.RECIPES[name].sources[0]
        row = next(line for line in readme.splitlines() if line.startswith(f"| {name.split('/')[1]} | "))
        assert source.path in row and source.sha256 in row, name


def test_only_extra_marks_the_optional_set_and_another_mark_is_an_error(tmp_path):
    (tmp_path / "a").mkdir()
    readme = tmp_path / "a" / "README.md"
    readme.write_text(f"| file | sha256 |\n| --- | --- |\n| one.csv | {'1' * 64} |\n\n"
                      f"| file | sha256 | set |\n| --- | --- | --- |\n| two.csv | {'2' * 64} | extra |\n"
                      f"| three.csv | 7 | {'3' * 64} |\n")
    assert data_records.manifest(tmp_path) == {"a/one.csv": "1" * 64}
    assert data_records.manifest(tmp_path, extra=True) == {"a/two.csv": "2" * 64}
    readme.write_text(f"| five.csv | {'5' * 64} | survey |\n")
    assert data_records.manifest(tmp_path, survey=True) == {"a/five.csv": "5" * 64}
    assert data_records.manifest(tmp_path) == {} and data_records.manifest(tmp_path, extra=True) == {}
    readme.write_text(f"| four.csv | {'4' * 64} | optional |\n")
    with pytest.raises(ValueError, match="four.csv.*'optional'"):
        data_records.manifest(tmp_path)


@pytest.mark.parametrize("args, want", [
    ([], "default"),
    (["--from", "."], "default"),
    (["--extra"], "both"),
    (["--extra", "--from", "."], "both"),
    (["brfd/KocaeliMCE_36lb.csv"], "named"),
    (["--survey"], "survey"),
    (["--survey", "--from", "."], "survey"),
    (["--survey", "--extra"], "all"),
])
def test_the_default_run_asks_for_the_default_set_only(monkeypatch, tmp_path, args, want):
    asked = {}

    def fake_fetch(records, dest_dir, from_dir):
        asked.update(records=dict(records), from_dir=from_dir)
        return []

    monkeypatch.setattr(fetch_data, "fetch", fake_fetch)
    monkeypatch.chdir(tmp_path)
    assert fetch_data.main([*args, "--to", str(tmp_path / "data")]) == 0
    extra, survey = data_records.manifest(extra=True), data_records.manifest(survey=True)
    expected = {"default": DEFAULT_SET, "both": {**DEFAULT_SET, **extra},
                "named": {"brfd/KocaeliMCE_36lb.csv": extra["brfd/KocaeliMCE_36lb.csv"]},
                "survey": survey, "all": {**DEFAULT_SET, **extra, **survey}}[want]
    assert asked["records"] == expected
    assert (asked["from_dir"] is None) == ("--from" not in args)


def test_an_optional_record_is_made_from_its_json_like_the_others(tmp_path, monkeypatch):
    """The download path of an optional record's recipe with its source served from a local file (file: URL),
    on a made-up damper test in the source's layout (rows of time, displacement, force, velocity, ...)."""
    doc = b'{"data": [[0.0, -0.25, 0.125, 1.0, 2.0, 3.0], [0.0009765625, -0.2500000000001, -3.5, 0, 0, 0]], "dt": 1}'
    recipe = fetch_data.RECIPES["brfd/d1_char_0.5Hz_35lb.csv"]
    src = a_source(tmp_path, {f"r/c/{recipe.sources[0].path}": doc})
    monkeypatch.setattr(fetch_data.Source, "url",
                        lambda s: "file://" + urllib.parse.quote(str(src / "r" / "c" / s.path)))
    source = fetch_data.Source("r", "c", recipe.sources[0].path, sha(doc))
    monkeypatch.setattr(fetch_data, "RECIPES", {"brfd/d1.csv": fetch_data.Recipe((source,), recipe.convert)})
    out = b"t,u,y\n0,-0.25,0.125\n0.0009765625,-0.25,-3.5\n"
    assert fetch_data.fetch({"brfd/d1.csv": sha(out)}, tmp_path / "data", None) == []
    assert (tmp_path / "data" / "brfd" / "d1.csv").read_bytes() == out


def test_a_missing_record_names_itself_and_the_fetch_command(tmp_path, monkeypatch):
    monkeypatch.setenv("BACKLASH_DATA", str(tmp_path))
    with pytest.raises(data_records.MissingRecord) as e:
        data_records.record_path("brfd/none.csv")
    assert "brfd/none.csv" in str(e.value) and "scripts/fetch_data.py" in str(e.value)
    (tmp_path / "brfd").mkdir()
    (tmp_path / "brfd" / "none.csv").write_text("t,u,y\n")
    assert data_records.record_path("brfd/none.csv") == tmp_path / "brfd" / "none.csv"


def a_source(tmp_path, files: dict[str, bytes]) -> pathlib.Path:
    src = tmp_path / "src"
    for name, data in files.items():
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        (src / name).write_bytes(data)
    return src


def test_copy_checks_every_hash_and_a_second_run_keeps_the_files(tmp_path, capsys):
    files = {"a/one.csv": b"t,u,y\n0,1,2\n", "b/two.csv": b"t,u,y\n0,3,4\n"}
    src = a_source(tmp_path, files)
    want = {name: sha(data) for name, data in files.items()}
    dest = tmp_path / "data"
    assert fetch_data.fetch(want, dest, src) == []
    assert {n: (dest / n).read_bytes() for n in files} == files
    first = capsys.readouterr().out
    assert first.count("sha256") == 2 and "from" in first
    (src / "a/one.csv").write_bytes(b"changed\n")  # a second run reads only what is in place
    assert fetch_data.fetch(want, dest, src) == []
    assert capsys.readouterr().out.count("in place") == 2


def test_a_wrong_hash_names_the_file_and_both_hashes_and_writes_nothing(tmp_path):
    src = a_source(tmp_path, {"a/one.csv": b"t,u,y\n0,1,2\n"})
    good = sha(b"t,u,y\n0,1,9\n")
    dest = tmp_path / "data"
    errors = fetch_data.fetch({"a/one.csv": good}, dest, src)
    assert len(errors) == 1
    assert "a/one.csv" in errors[0] and good in errors[0] and sha(b"t,u,y\n0,1,2\n") in errors[0]
    assert list((dest / "a").iterdir()) == []  # neither the record nor a temporary file


def test_a_record_missing_from_the_folder_is_an_error_and_the_others_are_copied(tmp_path):
    src = a_source(tmp_path, {"a/one.csv": b"1\n"})
    errors = fetch_data.fetch({"a/one.csv": sha(b"1\n"), "a/gone.csv": sha(b"2\n")}, tmp_path / "data", src)
    assert len(errors) == 1 and "a/gone.csv" in errors[0]
    assert (tmp_path / "data" / "a" / "one.csv").read_bytes() == b"1\n"


def test_the_command_fails_on_an_unknown_record_and_a_missing_folder(tmp_path):
    with pytest.raises(SystemExit):
        fetch_data.main(["no/such.csv", "--from", str(tmp_path)])
    with pytest.raises(SystemExit):
        fetch_data.main(["--from", str(tmp_path / "absent")])


def test_download_converts_each_source_once_and_checks_its_hash(tmp_path, monkeypatch):
    """The download path with the sources served from local files (file: URLs): the tanks recipe, whose two
    records share one source file."""
    table = b"uEst,uVal,yEst,yVal,Ts\n1.5,2.5,3.5,4.5,4\n1.25,2.25,3.25,4.25,4\n"
    src = a_source(tmp_path, {"repo/commit/dataBenchmark.csv": table})
    monkeypatch.setattr(fetch_data.Source, "url",
                        lambda s: "file://" + urllib.parse.quote(str(src / "repo" / "commit" / s.path)))
    source = fetch_data.Source("repo", "commit", "dataBenchmark.csv", sha(table))
    monkeypatch.setattr(fetch_data, "RECIPES", {
        "tanks/tanks_est.csv": fetch_data.Recipe((source,), fetch_data.tanks("Est").convert),
        "tanks/tanks_val.csv": fetch_data.Recipe((source,), fetch_data.tanks("Val").convert),
    })
    est, val = b"time,u,y\n0,1.5,3.5\n4,1.25,3.25\n", b"time,u,y\n0,2.5,4.5\n4,2.25,4.25\n"
    dest = tmp_path / "data"
    assert fetch_data.fetch({"tanks/tanks_est.csv": sha(est), "tanks/tanks_val.csv": sha(val)}, dest, None) == []
    assert (dest / "tanks/tanks_est.csv").read_bytes() == est
    assert (dest / "tanks/tanks_val.csv").read_bytes() == val
    (src / "repo/commit/dataBenchmark.csv").write_bytes(table + b"9,9,9,9,4\n")  # not what the recipe pins
    (dest / "tanks/tanks_est.csv").unlink()
    errors = fetch_data.fetch({"tanks/tanks_est.csv": sha(est)}, dest, None)
    assert len(errors) == 1 and "dataBenchmark.csv" in errors[0] and sha(table) in errors[0]
    assert sorted(p.name for p in (dest / "tanks").iterdir()) == ["tanks_val.csv"]


def mat_element(kind: int, payload: bytes) -> bytes:
    return struct.pack("<II", kind, len(payload)) + payload + b"\0" * (-len(payload) % 8)


def mat_small(kind: int, payload: bytes) -> bytes:
    """An element of at most 4 bytes in the tag's form (MATLAB writes short names so)."""
    return struct.pack("<HH", kind, len(payload)) + payload.ljust(4, b"\0")


def mat_vector(name: str, values: list, code: int = 9, fmt: str = "d") -> bytes:
    """A MAT-file level-5 real column vector (class double) whose data is stored as type `code`."""
    parts = (
        mat_element(6, struct.pack("<II", 6, 0))
        + mat_element(5, struct.pack("<ii", len(values), 1))
        + (mat_small(1, name.encode()) if len(name) <= 4 else mat_element(1, name.encode()))
        + mat_element(code, struct.pack(f"<{len(values)}{fmt}", *values))
    )
    return mat_element(14, parts)


def test_the_mat_reader_finds_plain_compressed_and_narrow_arrays(tmp_path):
    header = b"MATLAB 5.0 MAT-file".ljust(116, b" ") + b"\0" * 8 + struct.pack("<H", 0x0100) + b"IM"
    packed = zlib.compress(mat_vector("qm", [1e-5, 2.5e-5, -3.0]))
    body = (
        mat_vector("t", [0.0, 0.001, 0.002])
        + struct.pack("<II", 15, len(packed)) + packed
        + mat_vector("vir", [1, 2, 3], code=2, fmt="B")  # integers stored as uint8, as MATLAB does
        + mat_vector("a_long_name", [7.0])
    )
    (tmp_path / "d.mat").write_bytes(header + body)
    arrays = convert_records.read_mat_vectors(str(tmp_path / "d.mat"))
    assert arrays == {"t": [0.0, 0.001, 0.002], "qm": [1e-5, 2.5e-5, -3.0], "vir": [1.0, 2.0, 3.0],
                      "a_long_name": [7.0]}
    assert convert_records.convert_emps(str(tmp_path / "d.mat"), str(tmp_path / "e.csv")) == 3
    assert (tmp_path / "e.csv").read_text() == "t,u,y\n0,1,1e-05\n0.001,2,2.5e-05\n0.002,3,-3\n"


def mat_struct(name: str, fields: dict[str, bytes]) -> bytes:
    """A 1-by-1 MAT-file struct whose fields are the given matrix elements (their own names left empty)."""
    width = 8
    names = b"".join(f.encode().ljust(width, b"\0") for f in fields)
    parts = (
        mat_element(6, struct.pack("<II", 2, 0))
        + mat_element(5, struct.pack("<ii", 1, 1))
        + mat_element(1, name.encode())
        + mat_small(5, struct.pack("<i", width))
        + mat_element(1, names)
        + b"".join(fields.values())
    )
    return mat_element(14, parts)


def mat_matrix(name: str, rows: int, values: list) -> bytes:
    """A MAT-file real double matrix of `rows` rows, values in column order."""
    parts = (
        mat_element(6, struct.pack("<II", 6, 0))
        + mat_element(5, struct.pack("<ii", rows, len(values) // rows))
        + mat_element(1, name.encode())
        + mat_element(9, struct.pack(f"<{len(values)}d", *values))
    )
    return mat_element(14, parts)


def test_the_mat_reader_finds_struct_fields_and_rows_and_skips_objects(tmp_path):
    header = b"MATLAB 5.0 MAT-file".ljust(116, b" ") + b"\0" * 8 + struct.pack("<H", 0x0100) + b"IM"
    # An object (class 17) whose second part is a class name, not dimensions: skipped, as MATLAB's objects are.
    opaque = mat_element(14, mat_element(6, struct.pack("<II", 17, 0)) + mat_element(1, b"x")
                         + mat_element(1, b"MCOS") + mat_element(1, b"FileWrapper__"))
    rec = mat_struct("rec", {"time": mat_matrix("", 1, [0.5, 0.75, 1.0]),
                             "pos": mat_matrix("", 2, [1.0, 10.0, 2.0, 20.0, 3.0, 30.0])})
    (tmp_path / "r.mat").write_bytes(header + opaque + rec + mat_matrix("data", 3, [0, 1, 2, 5, 6, 7]))
    arrays = convert_records.read_mat_arrays(str(tmp_path / "r.mat"))
    assert set(arrays) == {"rec.time", "rec.pos", "data"}
    assert arrays["rec.pos"].dims == (2, 3) and arrays["rec.pos"].row(1) == [10.0, 20.0, 30.0]
    assert arrays["data"].column(1) == [5.0, 6.0, 7.0]
    assert convert_records.read_mat_vectors(str(tmp_path / "r.mat")) == {"data": [0.0, 1.0, 2.0, 5.0, 6.0, 7.0]}
    out = tmp_path / "o.csv"
    assert convert_records.convert_mat(str(tmp_path / "r.mat"), "rec.pos(2,:)", "rec.pos(1,:)", str(out),
                                       time="rec.time") == 3
    assert out.read_text() == "t,u,y\n0,10,1\n0.25,20,2\n0.5,30,3\n"
    convert_records.convert_mat(str(tmp_path / "r.mat"), "data(:,2)", "data(:,1)", str(out), dt=0.1)
    assert out.read_text() == "t,u,y\n0,5,0\n0.1,6,1\n0.2,7,2\n"


def test_a_table_is_read_by_column_name_or_by_index(tmp_path):
    (tmp_path / "a.csv").write_text('"V1","V2",\n0.5,-1.25,\n 0.000,3,\n')
    out = tmp_path / "o.csv"
    assert convert_records.convert_table(str(tmp_path / "a.csv"), "V2", "V1", 9.0, str(out)) == 2
    assert out.read_text() == "t,u,y\n0,-1.25,0.5\n9,3,0\n"
    (tmp_path / "b.dat").write_text("   6.4100000e+00\t   4.7660989e+00\t\r\n   3.41e+00\t 4.76e+00\t\r\n")
    convert_records.convert_table(str(tmp_path / "b.dat"), 0, 1, 1.0, str(out))
    assert out.read_text() == "t,u,y\n0,6.41,4.7660989\n1,3.41,4.76\n"
