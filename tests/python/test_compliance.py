"""Compliance beyond a single run: FMU state across processes, refused states, fmu-manipulation-toolbox.

- An FMU state serialised in one process (a subprocess running FMPy) and deserialised in another gives,
  stepped on with the same inputs, bit-for-bit the outputs the first process got; and back again: the
  second process serialises later, a third deserialises that, and all agree (the serialised bytes of the
  same state are identical in both processes).
- A state of the other FMU, and truncated, corrupted, empty or random byte strings are refused with
  fmi2Error and a logged reason.
- fmu-manipulation-toolbox (`fmutool -input X.fmu -check`, pip package fmu-manipulation-toolbox) finds no
  error and no warning in either FMU; skipped when the package is not installed.
"""
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

from conftest import LOG

# Runs in a fresh interpreter: one FMU instance, optionally restored from a serialised state, stepped over
# [k0, k1) with the given inputs; serialises the state at the requested steps; writes outputs as float.hex.
# FMPy's default callbacks are used there (one logger per process, so the proxy caveat of conftest does
# not arise).
WORKER = r'''
import json, sys
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave

job = json.load(open(sys.argv[1]))
md = read_model_description(job["fmu"])
vars_ = {v.name: v for v in md.modelVariables}
s = FMU2Slave(guid=md.guid, unzipDirectory=job["unzip"],
              modelIdentifier=md.coSimulation.modelIdentifier, instanceName=job["name"])
s.instantiate(loggingOn=False)
if job["state"] is None:
    s.setupExperiment(startTime=0.0)
    for name, value in job["params"].items():
        v = vars_[name]
        if v.type == "Integer":
            s.setInteger([v.valueReference], [int(value)])
        else:
            s.setReal([v.valueReference], [float(value)])
    s.enterInitializationMode()
    s.exitInitializationMode()
else:
    # Straight from 'instantiated': the state carries everything, the layer's state and time included.
    st = s.deSerializeFMUstate(open(job["state"], "rb").read())
    s.setFMUstate(st)
    s.freeFMUstate(st)
ins = [vars_[n].valueReference for n in job["inputs"]]
outs = [vars_[n].valueReference for n in job["outputs"]]
ts = job["Ts"]
rows = []
for k in range(job["k0"], job["k1"]):
    if str(k) in job["save"]:
        st = s.getFMUstate()
        open(job["save"][str(k)], "wb").write(s.serializeFMUstate(st))
        s.freeFMUstate(st)
    s.setReal(ins, [job["u"][k][i] for i in range(len(ins))])
    s.doStep(k * ts, ts)
    rows.append([x.hex() for x in s.getReal(outs)])
json.dump(rows, open(job["out"], "w"))
s.terminate()
s.freeInstance()
'''

CASES = {
    "plant": dict(
        file="BacklashPlant.fmu",
        params={"noise_std": 0.05, "noise_seed": 3, "Ts": 0.01, "c1": 0.3},
        inputs=["u"],
        outputs=["y", "w", "x"],
        Ts=0.01,
    ),
    "estimator": dict(
        file="MrgiaEstimator.fmu",
        params={"rho_min": 0.001, "Ts": 1.0},
        inputs=["u", "y"],
        outputs=["a1", "a2", "b0", "m2", "c1", "c2", "y_hat", "e"],
        Ts=1.0,
    ),
}


def _inputs(n):
    rng = np.random.default_rng(42)
    u = rng.uniform(-2.4, 2.4, n) * np.repeat(rng.uniform(0.3, 1.2, n // 10), 10)
    # A crude plant output for the estimator's y input (any bounded signal does for this test).
    y = np.zeros(n)
    for k in range(1, n):
        x = 0.8 * u[k - 1]
        y[k] = x - 0.5 if x > y[k - 1] + 0.5 else (1.5 * (x + 1.0) if x < y[k - 1] - 1.0 else y[k - 1])
    return [[float(a), float(b)] for a, b in zip(u, y)]


@pytest.fixture(scope="module")
def unzipped():
    dirs = {}

    def get(path):
        if path not in dirs:
            dirs[path] = str(extract(path))
        return dirs[path]

    yield get
    for d in dirs.values():
        shutil.rmtree(d, ignore_errors=True)


def _worker(tmp_path, tag, **job):
    spec = tmp_path / f"{tag}.json"
    job["out"] = str(tmp_path / f"{tag}.out.json")
    spec.write_text(json.dumps(job))
    r = subprocess.run([sys.executable, "-c", WORKER, str(spec)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"{tag}: worker failed\n{r.stdout}\n{r.stderr}"
    return json.loads(open(job["out"]).read())


@pytest.mark.parametrize("which", sorted(CASES))
def test_fmu_state_crosses_processes_both_ways(which, tmp_path, unzipped, plant_fmu, estimator_fmu):
    case = CASES[which]
    fmu = plant_fmu if which == "plant" else estimator_fmu
    n = 300
    u = _inputs(n)
    common = dict(fmu=fmu, unzip=unzipped(fmu), params=case["params"], inputs=case["inputs"],
                  outputs=case["outputs"], Ts=case["Ts"], u=u)
    s1, s2a, s2b = (str(tmp_path / f) for f in ("s1.bin", "s2a.bin", "s2b.bin"))
    # Process A: from the start; saves at 100 and at 200.
    a = _worker(tmp_path, "A", name="A", state=None, k0=0, k1=n, save={"100": s1, "200": s2a}, **common)
    # Process B: restores A's state of step 100 in a fresh instance; saves at 200.
    b = _worker(tmp_path, "B", name="B", state=s1, k0=100, k1=n, save={"200": s2b}, **common)
    assert b == a[100:], "B, restored from A's state at step 100, differs from A"
    # The same state serialises to the same bytes in both processes.
    assert open(s2a, "rb").read() == open(s2b, "rb").read()
    # Process C: restores B's state of step 200; process D restores A's.
    c = _worker(tmp_path, "C", name="C", state=s2b, k0=200, k1=n, save={}, **common)
    d = _worker(tmp_path, "D", name="D", state=s2a, k0=200, k1=n, save={}, **common)
    assert c == a[200:] and d == a[200:]
    # The run did something: outputs change over the record.
    vals = np.array([[float.fromhex(x) for x in row] for row in a])
    assert np.all(np.isfinite(vals)) and np.ptp(vals[:, 0]) > 0


def _slave(path, unzip, name):
    md = read_model_description(path)
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName=name)
    s.instantiate(callbacks=LOG.callbacks)
    return s


def _running(path, unzip, name, steps=20):
    s = _slave(path, unzip, name)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    vr_u = {v.name: v.valueReference for v in read_model_description(path).modelVariables}["u"]
    for k in range(steps):
        s.setReal([vr_u], [np.sin(0.3 * k) * 2.0])
        s.doStep(float(k), 1.0)
    return s


def _blob(path, unzip):
    s = _running(path, unzip, "donor")
    st = s.getFMUstate()
    blob = s.serializeFMUstate(st)
    s.freeFMUstate(st)
    s.terminate()
    s.freeInstance()
    return blob


def _corruptions(blob):
    yield "empty", b""
    for cut in (1, len(blob) // 3, len(blob) // 2, len(blob) - 1):
        yield f"truncated to {cut} of {len(blob)} bytes", blob[:cut]
    yield "first byte changed", b"[" + blob[1:]
    mid = len(blob) // 2
    yield "invalid UTF-8 in the middle", blob[:mid] + b"\xff" + blob[mid + 1:]
    yield "NUL bytes", b"\0" * len(blob)
    other = re.sub(rb"backlash-fmu-state/[0-9]+", b"backlash-fmu-state/999", blob)
    assert other != blob
    yield "other format tag", other
    yield "tag removed", blob.replace(b'"format"', b'"formax"')
    yield "random bytes", np.random.default_rng(7).integers(0, 256, len(blob), dtype=np.uint8).tobytes()
    yield "JSON, not a state", b'{"hello": "world"}'


@pytest.mark.parametrize("target,source", [("plant", "estimator"), ("estimator", "plant"),
                                           ("plant", "plant"), ("estimator", "estimator")])
def test_foreign_truncated_and_corrupted_states_are_refused(target, source, unzipped, plant_fmu,
                                                           estimator_fmu):
    paths = {"plant": plant_fmu, "estimator": estimator_fmu}
    blob = _blob(paths[source], unzipped(paths[source]))
    cases = list(_corruptions(blob))
    if source != target:
        cases.insert(0, (f"a state of the {source}", blob))
    for what, data in cases:
        s = _slave(paths[target], unzipped(paths[target]), "victim")
        before = len(LOG.lines)
        with pytest.raises(FMICallException) as e:
            s.deSerializeFMUstate(data)
        assert e.value.status == 3, f"{what}: status {e.value.status}"
        new = LOG.lines[before:]
        assert any(st == 3 and cat == "logStatusError" and msg.startswith("fmi2DeSerializeFMUstate: ")
                   for st, cat, msg in new), f"{what}: no reason logged: {new}"
        if source != target and what.startswith("a state of"):
            assert any("belongs to another FMU" in msg for _, _, msg in new), new
        # fmi2Error puts the instance in the error state; fmi2Reset brings it back.
        s.reset()
        s.freeInstance()
    # The intact blob is accepted by its own FMU.
    if source == target:
        s = _slave(paths[target], unzipped(paths[target]), "owner")
        st = s.deSerializeFMUstate(blob)
        s.setFMUstate(st)
        s.freeFMUstate(st)
        s.terminate()
        s.freeInstance()


# ------------------------------------------------------------------------------ fmu-manipulation-toolbox

def _fmutool_command():
    """How to run fmutool: the package in this interpreter, else $FMUTOOL, else `fmutool` on PATH."""
    if importlib.util.find_spec("fmu_manipulation_toolbox") is not None:
        return [sys.executable, "-c",
                "import sys; from fmu_manipulation_toolbox.cli.fmutool import fmutool; sys.exit(fmutool())"]
    exe = os.environ.get("FMUTOOL") or shutil.which("fmutool")
    return [exe] if exe else None


ANSI = re.compile(r"\x1b\[[0-9;]*m")


@pytest.mark.parametrize("name", ["BacklashPlant", "MrgiaEstimator"])
def test_fmu_manipulation_toolbox_check_finds_nothing(name, plant_fmu, estimator_fmu):
    cmd = _fmutool_command()
    if cmd is None:
        pytest.skip("fmu-manipulation-toolbox is not installed (pip install fmu-manipulation-toolbox==2.0)")
    path = plant_fmu if name == "BacklashPlant" else estimator_fmu
    r = subprocess.run(cmd + ["-input", path, "-check"], capture_output=True, text=True, timeout=300)
    text = ANSI.sub("", r.stdout + r.stderr)
    lines = [ln.strip() for ln in text.splitlines()]
    bad = [ln for ln in lines if ln.startswith(("ERROR", "WARNING", "CRITICAL"))]
    assert r.returncode == 0, f"fmutool exit {r.returncode}:\n{text}"
    assert not bad, "\n".join(bad)
    assert any("seems to be compliant with FMI-2.0" in ln for ln in lines), text
    assert any("No semantic error" in ln for ln in lines), text
