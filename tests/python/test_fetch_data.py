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


def test_the_manifest_lists_every_record_once_with_a_recipe():
    records = data_records.manifest()
    assert len(records) == 9, records
    assert all(len(h) == 64 for h in records.values())
    assert "emps/emps.csv" in records and "dc_generator/dc_generator.csv" in records
    assert set(fetch_data.RECIPES) == set(records)


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
