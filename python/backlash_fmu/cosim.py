"""A small co-simulation master for the plant + estimator pair, on fmpy's FMU2Slave (or FMU3Slave for the
FMI 3.0 FMUs of target/fmu3, behind the same calls: see `_Fmi3`).

Wiring (the FMUs' timing in docs/INTERFACE.md): at t_k = k*Ts the same input u(k) goes to plant.u and estimator.u, and the
plant's output y(k) (which depends on inputs up to u(k-delay) only: no direct feedthrough) goes to
estimator.y. The communication step from t_k then advances both by one sample: after it the estimator's
outputs are the estimates after sample k, and the plant's output is y(k+1).

    k = 0 .. n-1:
        y(k)        = plant.y                     (read before the step)
        plant.u     = estimator.u = u(k);  estimator.y = y(k)
        plant.doStep(t_k, Ts);  estimator.doStep(t_k, Ts)
        estimates after sample k = estimator.a1 .. c2, y_hat, e, updating

Used by the tests as the reference master that other importers (fmpy's container FMU, libcosim) are compared
against. Needs fmpy (`pip install "backlash-fmu[cosim]"`).
"""
import copy
import pathlib
import shutil
import sys

import numpy as np
from fmpy import extract, read_model_description
from fmpy.container_fmu.cli import create_container_fmu
from fmpy.container_fmu.config import Component, Configuration, Connection
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.model_description import CoSimulation, DefaultExperiment, ModelDescription, ModelVariable, Unknown

ESTIMATE_NAMES = ("a1", "a2", "a3", "a4", "b0", "b1", "b2", "b3", "b4", "m2", "c1", "c2")
STD_ERR_NAMES = tuple(f"{n}_se" for n in ESTIMATE_NAMES)
CHECKED = ("a1", "a2", "b0", "m2", "c1", "c2")
PAPER_TRUTH = {"a1": 0.45, "a2": 0.55, "b0": 0.8, "m2": 1.5, "c1": 0.5, "c2": 1.0}
PAPER_INPUT_VARIANCE = 1.93


def paper_input(n, seed):
    """White input uniform on [-A, A] with variance 1.93 (paper 000, section 4): A = sqrt(3 * 1.93)."""
    a = np.sqrt(3.0 * PAPER_INPUT_VARIANCE)
    return np.random.default_rng(seed).uniform(-a, a, n)


def max_rel_error(est_row, truth=None, names=ESTIMATE_NAMES):
    """Largest |estimate - truth| / |truth| over a1, a2, b0, m2, c1, c2.

    est_row is either a mapping name -> value or a sequence ordered as `names` (default ESTIMATE_NAMES).
    """
    truth = PAPER_TRUTH if truth is None else truth
    if not hasattr(est_row, "keys"):
        est_row = dict(zip(names, est_row))
    return max(abs(est_row[k] - truth[k]) / abs(truth[k]) for k in CHECKED)


_PROCESS_CALLBACKS = None  # (callbacks, the Python logger they call): kept for the life of the process


def use_callbacks(callbacks):
    """Instantiate this process's FMUs with `callbacks` (already registered with fmpy's logger proxy) instead
    of registering a new set: a process that has its own logger, such as a test session recording the FMUs'
    log lines, must not have the proxy redirected away from it."""
    global _PROCESS_CALLBACKS
    _PROCESS_CALLBACKS = (callbacks, None)


def process_callbacks():
    """One set of FMI callbacks per process, never freed: fmpy's native logger proxy keeps a pointer to the
    last Python logger registered, and a logger that is garbage-collected would leave it dangling. The
    default one prints the FMUs' errors to standard error."""
    global _PROCESS_CALLBACKS
    if _PROCESS_CALLBACKS is None:
        from ctypes import byref

        from fmpy.fmi2 import defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
        from fmpy.logging import addLoggerProxy

        def log(env, name, status, category, message):
            if status >= 3:  # error, fatal: worth seeing
                print(f"{name.decode()}: {message.decode()}", file=sys.stderr)

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(log)
        cb.allocateMemory = defaultCallbacks.allocateMemory
        cb.freeMemory = defaultCallbacks.freeMemory
        addLoggerProxy(byref(cb))
        _PROCESS_CALLBACKS = (cb, log)  # keep the Python function alive with the structure
    return _PROCESS_CALLBACKS[0]


def _callbacks(callbacks):
    return process_callbacks() if callbacks is None else callbacks


class _Fmi3:
    """An FMU3Slave behind the FMU2Slave calls this master makes: setupExperiment's start time goes to
    fmi3EnterInitializationMode, Real is Float64, Integer is Int32, and doStep's outputs (event handling, early
    return: never set by these FMUs) are checked and dropped."""

    def __init__(self, fmu):
        self.fmu = fmu
        self.start_time = 0.0

    def setupExperiment(self, startTime=0.0):
        self.start_time = startTime

    def enterInitializationMode(self):
        self.fmu.enterInitializationMode(startTime=self.start_time)

    def exitInitializationMode(self):
        self.fmu.exitInitializationMode()

    def getReal(self, vr):
        return self.fmu.getFloat64(vr)

    def setReal(self, vr, values):
        self.fmu.setFloat64(vr, values)

    def setInteger(self, vr, values):
        self.fmu.setInt32(vr, values)

    def getBoolean(self, vr):
        return self.fmu.getBoolean(vr)

    def setBoolean(self, vr, values):
        self.fmu.setBoolean(vr, values)

    def doStep(self, t, h):
        event, terminate, early, last = self.fmu.doStep(t, h)
        assert not (event or terminate or early), (event, terminate, early)
        assert last == t + h, (last, t + h)

    def terminate(self):
        self.fmu.terminate()

    def freeInstance(self):
        self.fmu.freeInstance()


class _Slave:
    """An instantiated FMU2Slave (or FMU3Slave behind `_Fmi3`) with its variables by name."""

    def __init__(self, path, instance_name, callbacks):
        self.md = read_model_description(path)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.unzipdir = extract(path)
        self.instantiated = False
        try:
            if self.md.fmiVersion.startswith("3"):
                from conftest import LOG3  # lazily, as LOG: the one session-wide FMI 3.0 logger

                fmu = FMU3Slave(
                    guid=self.md.instantiationToken,
                    unzipDirectory=self.unzipdir,
                    modelIdentifier=self.md.coSimulation.modelIdentifier,
                    instanceName=instance_name,
                )
                fmu.instantiate(logMessage=LOG3.record)
                self.fmu = _Fmi3(fmu)
            else:
                self.fmu = FMU2Slave(
                    guid=self.md.guid,
                    unzipDirectory=self.unzipdir,
                    modelIdentifier=self.md.coSimulation.modelIdentifier,
                    instanceName=instance_name,
                )
                self.fmu.instantiate(callbacks=callbacks)
        except Exception:
            shutil.rmtree(self.unzipdir, ignore_errors=True)
            raise
        self.instantiated = True

    def vr(self, name):
        return self.vars[name].valueReference

    def set_start(self, values):
        for name, value in (values or {}).items():
            v = self.vars[name]
            if v.type in ("Real", "Float64"):
                self.fmu.setReal([v.valueReference], [float(value)])
            elif v.type in ("Integer", "Int32", "Enumeration"):
                self.fmu.setInteger([v.valueReference], [int(value)])
            elif v.type == "Boolean":
                self.fmu.setBoolean([v.valueReference], [bool(value)])
            elif v.type == "String":
                self.fmu.setString([v.valueReference], [str(value)])
            else:
                raise TypeError(f"{name}: unsupported type {v.type}")

    def free(self):
        try:
            if self.instantiated:
                self.fmu.freeInstance()
        finally:
            self.instantiated = False
            shutil.rmtree(self.unzipdir, ignore_errors=True)


def run_pair(plant_fmu, estimator_fmu, u, plant_start=None, estimator_start=None, ts=1.0, record_every=1,
             checkpoints=None, callbacks=None, plant_events=None, estimator_outputs=(), estimator_events=None):
    """Co-simulate plant and estimator over the samples u (one communication step of ts per sample).

    Returns a dict of numpy arrays:
      'y'         plant output y(k), k = 0..n-1 (what the estimator received as sample k)
      'samples'   the sample counts (k + 1) at which the estimator outputs were recorded: every
                  `record_every` samples (the last sample always included), or exactly `checkpoints`
      'estimates' rows [a1, a2, a3, a4, b0..b4, m2, c1, c2] after that many samples
      'std_err'   rows [a1_se, .., c2_se] at the same points (the `refine` setting's standard errors)
      'updating', 'y_hat', 'e'   the estimator's other outputs at the same points
      'names'     the column names of 'estimates'
    `plant_events` maps a sample index k to {name: value} set on the plant before it reads u(k) (tunable
    parameters such as c1, c2: a wear step in the middle of a run).
    `estimator_events` does the same on the estimator before it reads sample k (its input `wear_reset`).
    `estimator_outputs` names further estimator outputs (Real or Boolean, e.g. the wear monitor's) recorded at
    the same points into 'outputs' (a dict of arrays by name).
    """
    u = np.asarray(u, dtype=float)
    n = len(u)
    if checkpoints is not None:
        want = sorted({int(c) for c in checkpoints})
        if want and (want[0] < 1 or want[-1] > n):
            raise ValueError(f"checkpoints must lie in 1..{n}")
    else:
        want = sorted(set(range(record_every, n + 1, record_every)) | ({n} if n else set()))
    want_set = set(want)
    cb = _callbacks(callbacks)
    plant = est = None
    try:
        plant = _Slave(plant_fmu, "plant", cb)
        est = _Slave(estimator_fmu, "estimator", cb)
        for s, start in ((plant, plant_start), (est, estimator_start)):
            s.fmu.setupExperiment(startTime=0.0)
            s.set_start({"Ts": ts, **(start or {})})
            s.fmu.enterInitializationMode()
            s.fmu.exitInitializationMode()

        p, e = plant.fmu, est.fmu
        vr_py, vr_pu = [plant.vr("y")], [plant.vr("u")]
        vr_eu_ey = [est.vr("u"), est.vr("y")]
        vr_out = [est.vr(k) for k in ESTIMATE_NAMES + STD_ERR_NAMES] + [est.vr("y_hat"), est.vr("e")]
        vr_upd = [est.vr("updating")]
        extra = {name: (est.vr(name), est.vars[name].type == "Boolean") for name in estimator_outputs}
        extra_rows = {name: [] for name in estimator_outputs}

        y = np.empty(n)
        rows, upd = [], []
        events = {int(k): v for k, v in (plant_events or {}).items()}
        est_events = {int(k): v for k, v in (estimator_events or {}).items()}
        for k in range(n):
            t = k * ts
            if k in events:
                plant.set_start(events[k])
            yk = p.getReal(vr_py)[0]
            y[k] = yk
            uk = float(u[k])
            p.setReal(vr_pu, [uk])
            e.setReal(vr_eu_ey, [uk, yk])
            if k in est_events:
                est.set_start(est_events[k])
            p.doStep(t, ts)
            e.doStep(t, ts)
            if k + 1 in want_set:
                rows.append(e.getReal(vr_out))
                upd.append(e.getBoolean(vr_upd)[0])
                for name, (vr, boolean) in extra.items():
                    extra_rows[name].append(e.getBoolean([vr])[0] if boolean else e.getReal([vr])[0])
        for s in (p, e):
            s.terminate()
        m = len(ESTIMATE_NAMES)
        rows = np.array(rows, dtype=float).reshape(len(rows), 2 * m + 2)
        return {
            "y": y,
            "samples": np.array(want, dtype=int),
            "estimates": rows[:, :m],
            "std_err": rows[:, m : 2 * m],
            "y_hat": rows[:, -2],
            "e": rows[:, -1],
            "updating": np.array(upd, dtype=bool),
            "names": list(ESTIMATE_NAMES),
            # Booleans as bool arrays (FMPy returns them as ints, whose ~ would be -1 and -2, not a mask).
            "outputs": {name: np.array(v, dtype=bool if extra[name][1] else float)
                        for name, v in extra_rows.items()},
        }
    finally:
        for s in (est, plant):
            if s is not None:
                s.free()


# --- The pair as one container FMU (fmpy.container_fmu) -------------------------------------------------------

CONTAINER_OUTPUTS = ("a1", "a2", "b0", "m2", "c1", "c2")  # estimator outputs the container exposes


def _float64(variable):
    """A copy of a component's FMI 2 Real variable with type 'Float64', for a container Connection.

    fmpy 0.3.32 writes resources/container.json from the Configuration. For the container's own variables
    (write_configuration's 'variables') it maps the FMI 2 type names Real -> Float64 and Integer -> Int32, but
    for a Connection it copies `startConnectors[0].type` verbatim. The container binary deserialises that
    field into its VariableType enum, which has FMI 3 names only; with the components' own ModelVariables the
    connection type is 'Real' and the container FMU refuses to instantiate:
        (3, 'logStatusError', "Failed to read configuration file .../resources/container.json. Failed to parse
         configuration file: unknown variant `Real`, expected one of `Float32`, `Float64`, `Int8`, ...")
    The binary then exchanges a 'Float64' connection between FMI 2 components with fmi2GetReal/fmi2SetReal.
    """
    v = copy.copy(variable)
    v.type = "Float64"
    return v


def build_container(plant_fmu, estimator_fmu, unzipdir, filename):
    plant_fmu, estimator_fmu = pathlib.Path(plant_fmu), pathlib.Path(estimator_fmu)
    pmd, emd = read_model_description(plant_fmu), read_model_description(estimator_fmu)
    pv = {v.name: v for v in pmd.modelVariables}
    ev = {v.name: v for v in emd.modelVariables}
    # Component.filename's stem names the folder resources/<stem> the component is unpacked to.
    plant = Component(name="plant", filename=plant_fmu, modelDescription=pmd)
    est = Component(name="estimator", filename=estimator_fmu, modelDescription=emd)

    def out(name, type_="Real"):
        return ModelVariable(name=name, type=type_, causality="output", variability="discrete", initial="calculated")

    # The container binary answers value reference 0 with its own time and value reference i >= 1 with the
    # i-th entry of variableMappings; create_container_fmu numbers modelVariables 0, 1, 2, ... So the first
    # model variable must be the independent 'time' and the rest must follow variableMappings' order.
    time_var = ModelVariable(name="time", type="Real", causality="independent", variability="continuous")
    u = ModelVariable(name="u", type="Real", causality="input", variability="discrete", start="0")
    mappings = {u: [(plant, pv["u"]), (est, ev["u"])]}  # one container input drives both components' u
    outputs = [out("y")]
    mappings[outputs[0]] = [(plant, pv["y"])]
    for name in CONTAINER_OUTPUTS:
        v = out(name)
        mappings[v] = [(est, ev[name])]
        outputs.append(v)
    upd = out("updating", "Boolean")  # FMI 2 Boolean outputs map fine (fmi2GetBoolean on the component)
    mappings[upd] = [(est, ev["updating"])]
    outputs.append(upd)

    md = ModelDescription(
        fmiVersion="2.0",
        modelName="BacklashPair",
        instantiationToken="{5b0f7c1e-3d1a-4c55-9a43-0b1a5c0e9a11}",
        description="BacklashPlant + MrgiaEstimator, y -> y, one input u to both",
        defaultExperiment=DefaultExperiment(startTime="0", stepSize="1"),
        # fixedInternalStepSize is not written to an FMI 2 modelDescription.xml but goes to container.json as
        # the container's internal step: it must be the components' Ts (one sample per step).
        coSimulation=CoSimulation(modelIdentifier="container_fmu", fixedInternalStepSize=1.0),
        modelVariables=[time_var, u] + outputs,
        outputs=[Unknown(variable=v) for v in outputs],
        initialUnknowns=[Unknown(variable=v) for v in outputs],
    )
    config = Configuration(
        parallelDoStep=False,
        modelDescription=md,
        components=[plant, est],
        connections=[Connection(plant, [_float64(pv["y"])], est, [_float64(ev["y"])])],
        variableMappings=mappings,
    )
    unzipdir.mkdir(parents=True, exist_ok=True)  # create_container_fmu removes and recreates it
    create_container_fmu(config, unzipdir, filename)
    return filename
