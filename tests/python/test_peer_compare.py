"""The peers of scripts/peer_compare.py on synthetic records whose answer is known, its committed numbers
(docs/measured_records.json) and the ratchet on a stand-in for the program."""
import importlib.util
import math
import pathlib
import sys

import numpy as np
import pytest
from scipy.signal import lfilter

ROOT = pathlib.Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("peer_compare", ROOT / "scripts" / "peer_compare.py")
pc = importlib.util.module_from_spec(_spec)
sys.modules["peer_compare"] = pc  # dataclasses look their module up while the file runs
_spec.loader.exec_module(pc)

NOISE = 0.02


def linear_record(n=1500, seed=1):
    """y = x + e, x(k) = 0.7 x(k-1) + 0.5 u(k-2) + 0.3 from rest: ARX(1, 0, 2) with a constant."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    x = lfilter([0.0, 0.0, 0.5], [1.0, -0.7], u) + lfilter([0.3], [1.0, -0.7], np.ones(n))
    return u, x + NOISE * rng.standard_normal(n)


def polynomial_record(n=800, seed=2):
    """y = x + e, x(k) = 0.5 x(k-1) + 0.4 u(k-1) + 0.3 u(k-1)^2 from rest: a degree-2 NARX."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.0, 1.0, n)
    x = np.zeros(n)
    for k in range(1, n):
        x[k] = 0.5 * x[k - 1] + 0.4 * u[k - 1] + 0.3 * u[k - 1] ** 2
    return u, x + NOISE * rng.standard_normal(n)


def test_split_is_diagnoses_rule():
    assert pc.split_index(273) == 191
    assert pc.split_index(10) == 7
    assert pc.split_index(2) == 1


def test_block_means_drop_the_partial_block():
    assert pc.block_means(np.arange(10.0), 4).tolist() == [1.5, 5.5]


def test_fit_arx_recovers_the_true_coefficients():
    u, y = linear_record()
    m = pc.fit_arx(u, y, 1, 0, 2)
    assert m.a == pytest.approx([-0.7], abs=0.01)
    assert m.b == pytest.approx([0.5], abs=0.01)
    assert m.c == pytest.approx(0.3, abs=0.01)


def test_arx_peer_heldout_error_is_the_noise_level():
    u, y = linear_record()
    p = pc.arx_peer(u, y)
    assert p.structure, p
    assert 0.85 * NOISE < p.heldout_rmse < 1.2 * NOISE, p


def test_arx_free_run_starts_at_rest_at_the_given_point():
    # y(k) = 0.5 y(k-1) + u(k-1) + 0.5: at rest at u = 1 its output is 3
    m = pc.ArxModel(1, 0, 1, np.array([-0.5]), np.array([1.0]), 0.5)
    assert m.simulate(np.ones(4), y_rest=3.0, u_rest=1.0) == pytest.approx([3.0] * 4)
    assert m.simulate(np.array([1.0, 1.0, 0.0]), y_rest=0.0, u_rest=0.0) == pytest.approx([0.5, 1.75, 2.375])
    assert m.simulate(np.array([1.0, 1.0]), y_rest=2.0, u_rest=4.0) == pytest.approx([5.5, 4.25])


def test_a_diverging_free_run_is_not_eligible():
    assert not pc.bounded(None)
    assert not pc.bounded(np.array([1.0, 2.0 * pc.DIVERGED_FACTOR]))
    assert not pc.bounded(np.array([1.0, np.nan]))
    assert pc.bounded(np.array([-1.0, 1.0]))


def test_narx_peer_finds_the_polynomial_and_arx_does_not():
    u, y = polynomial_record()
    narx = pc.narx_peer(u, y, lags=[1, 2], degrees=(2,))
    arx = pc.arx_peer(u, y)
    assert narx.reason == "", narx
    assert narx.heldout_rmse < 1.3 * NOISE, narx
    assert arx.heldout_rmse > 3 * NOISE, arx


def test_narx_simulation_from_rest_by_codes():
    # y(k) = 0.5 y(k-1) + 2 u(k-1) u(k-2) + 1, from rest (y and u 0 before the first sample)
    m = pc.NarxModel(np.array([[1001, 0], [2001, 2002], [0, 0]]), np.array([0.5, 2.0, 1.0]))
    u = np.array([1.0, 2.0, 3.0, 0.0])
    y = m.simulate(u, y_rest=0.0, u_rest=0.0, bound=1e9)
    assert y.tolist() == [1.0, 1.5, 1.75 + 4.0, 0.5 * 5.75 + 12.0 + 1.0]


def test_diverging_narx_simulation_is_refused():
    m = pc.NarxModel(np.array([[1001, 1001]]), np.array([1.0]))  # y(k) = y(k-1)^2 from y = 2
    assert m.simulate(np.zeros(50), y_rest=2.0, u_rest=0.0, bound=1e6) is None


def test_constant_record_gives_a_reason_not_an_exception():
    p = pc.narx_peer(np.ones(100), np.arange(100.0))
    assert math.isnan(p.heldout_rmse) and "constant" in p.reason


def test_run_process_stops_at_the_timeout():
    code, _, _, seconds, _ = pc.run_process(["sleep", "5"], timeout=0.2)
    assert code is None
    assert seconds < 2.0


def a_record(tmp_path, monkeypatch, name="x/r.csv"):
    """A small record under a data folder of its own (BACKLASH_DATA), and its Record."""
    monkeypatch.setenv("BACKLASH_DATA", str(tmp_path))
    (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / name).write_text("time,u,y\n" + "".join(f"{k},{k % 3},{k % 5}\n" for k in range(60)))
    return pc.Record("synthetic", name)


def test_missing_binary_gives_the_reason(tmp_path, monkeypatch):
    rec = a_record(tmp_path, monkeypatch)
    d = pc.run_diagnose(str(tmp_path / "no-such-program"), rec, timeout=1.0)
    assert "not found" in d.reason


def test_missing_record_is_an_error_naming_the_fetch_command(tmp_path, monkeypatch):
    monkeypatch.setenv("BACKLASH_DATA", str(tmp_path))
    with pytest.raises(FileNotFoundError, match="scripts/fetch_data.py"):
        pc.run_diagnose("backlash", pc.Record("absent", "x/none.csv"), timeout=1.0)
    with pytest.raises(FileNotFoundError, match="x/none.csv"):
        pc.read_record(pc.Record("absent", "x/none.csv"))


def fake_backlash(tmp_path, after):
    """A stand-in for the program: `diagnose` prints a JSON answer whose final held-out error is `after`."""
    doc = {"na": 1, "nb": 0, "delay": 1, "decimate": 1, "rate": {"chosen_by": "data"}, "before": {"rmse": 2.0},
           "after": {"rmse": after}, "linear": {"rmse": 3.0}, "effects": []}
    prog = tmp_path / "backlash"
    prog.write_text(f"#!{sys.executable}\nimport json\nprint(json.dumps({doc!r}))\n")
    prog.chmod(0o755)
    return str(prog)


def committed(after):
    return pc.Entry("synthetic", pc.DiagnoseResult(after=after, decimate=1), [])


@pytest.mark.parametrize("now, passes", [(1.0, True), (1.0199, True), (0.5, True), (1.0201, False)])
def test_the_ratchet_fails_only_beyond_two_percent_and_names_both_numbers(tmp_path, monkeypatch, now, passes):
    rec = a_record(tmp_path, monkeypatch)
    ok, line = pc.ratchet(rec, committed(1.0), fake_backlash(tmp_path, now), timeout=30.0)
    assert ok == passes, line
    assert line.startswith("synthetic") and f"{now:.6g}" in line and "committed 1" in line


def test_the_ratchet_fails_without_a_committed_number_or_an_answer(tmp_path, monkeypatch):
    rec = a_record(tmp_path, monkeypatch)
    ok, line = pc.ratchet(rec, None, fake_backlash(tmp_path, 1.0), timeout=30.0)
    assert not ok and "--update" in line
    ok, line = pc.ratchet(rec, committed(1.0), str(tmp_path / "absent"), timeout=30.0)
    assert not ok and "not found" in line
    code = pc.run_ratchet([rec], {"synthetic": committed(0.5)}, fake_backlash(tmp_path, 1.0), timeout=30.0)
    assert code == 1


def ratchet_setup(tmp_path, monkeypatch):
    """A default record in place and an optional one not fetched, with committed numbers for both."""
    rec = a_record(tmp_path, monkeypatch)
    extra = pc.Record("synthetic-extra", "x/not-fetched.csv", optional=True)
    monkeypatch.setattr(pc, "RECORDS", [rec, extra])
    monkeypatch.setattr(pc, "load", lambda: {"synthetic": committed(1.0), "synthetic-extra": committed(1.0)})
    return ["--ratchet", "--backlash", fake_backlash(tmp_path, 1.0)]


def test_the_ratchet_skips_an_optional_record_not_in_place(tmp_path, monkeypatch, capsys):
    args = ratchet_setup(tmp_path, monkeypatch)
    assert pc.main(args) == 0
    out, err = capsys.readouterr()
    assert "ok      synthetic:" in out and "synthetic-extra" not in out
    assert "skipped synthetic-extra: x/not-fetched.csv is not in place" in err and "--extra" in err
    # Named, it is required; fetched, it is checked like the others.
    assert pc.main([*args, "--records", "synthetic-extra"]) == 1
    assert "x/not-fetched.csv" in capsys.readouterr().err
    (tmp_path / "x" / "not-fetched.csv").write_text((tmp_path / "x" / "r.csv").read_text())
    assert pc.main(args) == 0
    assert "ok      synthetic-extra:" in capsys.readouterr().out


def test_a_missing_record_of_the_default_set_still_fails_the_ratchet(tmp_path, monkeypatch, capsys):
    args = ratchet_setup(tmp_path, monkeypatch)
    (tmp_path / "x" / "r.csv").unlink()
    assert pc.main(args) == 1
    assert "x/r.csv" in capsys.readouterr().err


def test_the_optional_records_are_the_damper_tests_of_data_brfd():
    optional = [r for r in pc.RECORDS if r.optional]
    assert len(optional) == 6 and len([r for r in pc.RECORDS if not r.optional]) == 9
    import data_records

    extra = data_records.manifest(extra=True)
    assert sorted(r.file for r in optional) == sorted(extra)
    assert not {r.file for r in pc.RECORDS if not r.optional} - set(data_records.manifest())
    sine = pc.record_named("brfd-sine")
    for r in optional:  # measured as the damper records of the default set
        assert (r.time_col, r.decimate, r.fallback) == (sine.time_col, sine.decimate, sine.fallback), r.name


def test_the_committed_numbers_cover_every_record_at_both_rates():
    entries = pc.load()
    assert sorted(entries) == sorted(r.name for r in pc.RECORDS) and len(entries) == 15
    for name, e in entries.items():
        d = e.diagnose
        assert d.reason == "" and math.isfinite(d.after), name
        rates = {p.decimate for p in e.peers}
        assert rates == {1, d.decimate}, (name, rates)
        # At diagnose's rate (the table's ratio) both peers have a number; at the file's rate a peer may have
        # none only with the reason (brfd-kocaeli-mce: every NARX structure diverges on the 27342 samples).
        at = e.peers_at(d.decimate)
        assert math.isfinite(at.arx.heldout_rmse) and math.isfinite(at.narx.heldout_rmse), (name, at)
        for p in e.peers:
            for peer in (p.arx, p.narx):
                assert math.isfinite(peer.heldout_rmse) or peer.reason.startswith("all 8 structures"), (name, p)


def test_the_committed_file_round_trips(tmp_path):
    entries = pc.load()
    pc.save(entries, tmp_path / "m.json")
    assert pc.load(tmp_path / "m.json") == entries


def test_a_row_compares_with_the_best_peer_at_diagnoses_rate():
    peers = [pc.PeerSet(1, 100, 9.0, pc.PeerResult("1,1,1", 4.0), pc.PeerResult("lag 1", 3.0)),
             pc.PeerSet(4, 25, 8.0, pc.PeerResult("1,1,1", 2.0), pc.PeerResult("lag 1", 2.5))]
    r = pc.row(pc.Entry("x", pc.DiagnoseResult(after=1.0, decimate=4, rate_by="data"), peers))
    assert (r["ARX"], r["NARX"], r["after / best peer"]) == ("2", "2.5", "0.5")
    assert (r["ARX, file's rate"], r["NARX, file's rate"], r["N"]) == ("4", "3", "25 (100 as given)")


def test_json_of_the_new_and_the_old_cli():
    new = {"na": 1, "nb": 0, "delay": 2, "before": {"rmse": 2.0}, "after": {"rmse": 1.0},
           "linear": {"rmse": 1.5}, "effects": [{"id": "friction"}, {"id": "saturation"}]}
    r = pc.DiagnoseResult()
    pc.fill_from_json(r, new)
    assert (r.structure, r.before, r.after, r.linear, r.effects) == ("1,0,2", 2.0, 1.0, 1.5, "friction+saturation")
    old = {"na": 0, "nb": 0, "delay": 1, "before": {"rmse": 2.0},
           "after": {"rmse": 0.5, "error_kind": "one-step prediction"}, "effect": {"id": None}}
    r = pc.DiagnoseResult()
    pc.fill_from_json(r, old)
    assert math.isnan(r.linear) and r.effects == "none" and "one-step" in r.reason


def test_peak_memory_is_the_childs_not_this_processs():
    big = [sys.executable, "-c", "x = bytearray(150 * 1024 * 1024); x[::4096] = b'1' * len(x[::4096])"]
    code, _, _, _, peak = pc.run_process(big, timeout=30.0)
    assert code == 0 and 150 < peak < 300
    _, _, _, _, small = pc.run_process(["true"], timeout=30.0)
    assert small < 20
