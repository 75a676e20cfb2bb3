"""`backlash identify mrgia --json` against the independent NumPy MRGIA of mrgia_reference.py.

The paper 000 example (section 4: a = (0.45, 0.55), b0 = 0.8, m2 = 1.5, c1 = 0.5, c2 = 1, input white noise of
variance 1.93) with output noise at SNR 43, simulated by the NumPy plant of reference.py. The two estimators
share no code; they agree to rounding (1e-9 relative) as long as no gate decision of eq. (42) is a near-tie,
which these records do not contain. The agreement is checked on the paper's setting, the recommended one and
an over-parameterised order (nb = 1), and the estimate is also checked to be near the truth (so that the
agreement is not that of two stuck estimators).
"""
import json
import subprocess

import numpy as np
import pytest

from mrgia_reference import identify
from reference import simulate

TRUTH = {"a": [0.45, 0.55], "b": [0.8], "m2": 1.5, "c1": 0.5, "c2": 1.0}


def record(n, seed, snr=43.0):
    rng = np.random.default_rng(seed)
    amp = np.sqrt(3 * 1.93)
    u = rng.uniform(-amp, amp, n)
    _, w = simulate(u)
    y = w + rng.normal(0.0, np.std(w) / snr, n)
    return u, y


def write_csv(path, u, y):
    t = np.arange(len(u), dtype=float)
    np.savetxt(path, np.column_stack([t, u, y]), delimiter=",", header="time,u,y", comments="", fmt="%.17g")


def flat(est):
    return np.array(est["a"] + est["b"] + [est["m2"], est["c1"], est["c2"]])


@pytest.mark.parametrize(
    "na,nb,recommended,seed",
    [(2, 0, False, 1), (2, 0, True, 2), (2, 1, True, 3)],
    ids=["paper", "recommended", "nb=1"],
)
def test_cli_agrees_with_numpy_reference(cli, tmp_path, na, nb, recommended, seed):
    n = 3000
    u, y = record(n, seed)
    csv = tmp_path / "rec.csv"
    write_csv(csv, u, y)
    cmd = [cli, "identify", "mrgia", str(csv), "--na", str(na), "--nb", str(nb), "--delay", "1", "--json"]
    if recommended:
        cmd.append("--recommended")
    got = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    ref = identify(u, y, na, nb, 1, rho_exp=0.75 if recommended else 0.25)
    want = flat(ref.estimate())
    have = flat(got)
    assert got["samples"] == n
    np.testing.assert_allclose(have, want, rtol=1e-9, atol=1e-12)
    # Not two stuck estimators: the estimate is near the truth (the extra b1 near 0).
    truth = np.array(TRUTH["a"] + TRUTH["b"] + [0.0] * nb + [TRUTH["m2"], TRUTH["c1"], TRUTH["c2"]])
    assert np.max(np.abs(have - truth)) < 0.15, have
