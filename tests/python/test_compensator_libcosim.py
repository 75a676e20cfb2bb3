"""The adaptive compensation loop in a second master, libcosim (Open Simulation Platform, through libcosimpy
0.0.6): BacklashPlant, MrgiaEstimator (recommended, refine, a memory) and BacklashCompensator as three local
slaves of one fixed-step execution, with the libcosim connection plant.y -> estimator.y. This script is the
rest of the master: it passes the estimator's m2, c1, c2 to the compensator's inputs of the same names, sets
the reference, the plant's wear and u through an override manipulator, and computes u(k) from the
compensator's v by the linear block's feed-forward inverse (as the library's loop, src/compensate/adaptive.rs).

Timing. libcosim's fixed-step algorithm steps every slave, then passes values (connections, overrides) for
the next step (a Jacobi master); every unit (Ts = 1 s) latches its inputs at t_k and answers sample k when a
step reaches t_{k+1}; a get between instants answers for the inputs as they are then. So the estimate after
samples 0..k-1 appears at t_k, the instant the plant latches u(k): no step is left in which the compensator
could answer for it. What this master runs is the library loop with `estimate_lag` 1 (the inverses at
sample k use the estimate after 0..k-2), on steps of Ts/2: at t_k - Ts/2 the script gives the compensator
r(k + d) and the estimate after 0..k-2; the half step to t_k commits sample k - 1 (the inputs latched at
t_{k-1}) and answers v(k) for the new inputs, which the step from t_k then latches as sample k's. At t_k the
script reads v(k), computes u(k) and sets it (with the wear of sample k) for the plant's and the
estimator's step from t_k; plant and estimator ignore what is set at the half steps (sampled-data timing,
docs/INTERFACE.md). Through a libcosim connection estimator -> compensator the estimate after 0..k-1 would
reach the compensator at t_k and be latched as sample k's, against the v(k) read for the earlier one.

Same numbers: y against `backlash compensate --estimate-lag 1 --out` sample by sample, bit for bit (the
compensator's first commit, sample 0 during the warm-up, whose v is not used, sees the compensator's start
estimate instead of the estimator's theta(0), which no step has reported yet).
"""
import json
import subprocess

import numpy as np

from test_compensator_fmpy import (  # noqa: F401 (compensator_fmu: a fixture)
    PAPER,
    WARMUP,
    _invertible,
    compensator_fmu,
    write_reference,
)

NS = 1_000_000_000  # libcosim time is integer nanoseconds; Ts = 1 s
LINEAR = ["a1", "a2", "b0"]
BACKLASH = ["m2", "c1", "c2"]


class _Master:
    """The three slaves in one libcosim execution, the connection, the override and a last-value observer."""

    def __init__(self, plant_fmu, estimator_fmu, compensator_fmu, noise_std, memory):
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
        from libcosimpy.CosimManipulator import CosimManipulator
        from libcosimpy.CosimObserver import CosimObserver
        from libcosimpy.CosimSlave import CosimLocalSlave

        log_output_level(CosimLogLevel.ERROR)
        self.ex = CosimExecution.from_step_size(NS // 2)
        self.idx, self.vr = {}, {}
        for name, path in (("plant", plant_fmu), ("estimator", estimator_fmu), ("compensator", compensator_fmu)):
            i = self.ex.add_local_slave(CosimLocalSlave(fmu_path=str(path), instance_name=name))
            assert i >= 0, f"libcosim could not load {path}"
            self.idx[name] = i
            self.vr[name] = {v.name.decode(): v.reference for v in self.ex.slave_variables(i)}
        self._connect("plant", "y", "estimator", "y")
        e = self.idx["estimator"]
        assert self.ex.boolean_initial_value(e, self.vr["estimator"]["recommended"], True)
        assert self.ex.boolean_initial_value(e, self.vr["estimator"]["refine"], True)
        assert self.ex.real_initial_value(e, self.vr["estimator"]["rho_min"], 1.0 / memory)
        p = self.idx["plant"]
        assert self.ex.real_initial_value(p, self.vr["plant"]["noise_std"], noise_std)
        assert self.ex.integer_initial_value(p, self.vr["plant"]["noise_seed"], 0)
        self.override = CosimManipulator.create_override()
        assert self.ex.add_manipulator(self.override)
        self.last = CosimObserver.create_last_value()
        assert self.ex.add_observer(self.last)

    def _connect(self, a, out, b, inp):
        assert self.ex.connect_real_variables(self.idx[a], self.vr[a][out], self.idx[b], self.vr[b][inp]) == 0

    def set(self, slave, values):
        """Queued; applied when the next step commences."""
        refs = [self.vr[slave][n] for n in values]
        assert self.override.slave_real_values(self.idx[slave], refs, [float(x) for x in values.values()])

    def get(self, slave, names):
        """The values read after the last step."""
        return self.last.last_real_values(self.idx[slave], [self.vr[slave][n] for n in names])

    def step(self):
        assert self.ex.step()


def run_loop(plant_fmu, estimator_fmu, compensator_fmu, r, noise_std, ramp, memory):
    """The library loop with estimate lag 1 (module docs) in libcosim; returns y(0..n-1) (y(0), before the
    first step, which libcosim's observers do not see, as nan)."""
    n, d = len(r), PAPER["delay"]
    m = _Master(plant_fmu, estimator_fmu, compensator_fmu, noise_std, memory)
    a, b = [0.0, 0.0], [1.0]  # the estimator's theta(0): x(k) = u(k - d)
    lagged = None  # the estimate after samples 0..k-2 (none before sample 2: theta(0) stays)
    x_hist, u_hist = [0.0] * 4, [0.0] * 4
    y = np.full(n, np.nan)
    m.set("compensator", {"r": r[min(d, n - 1)]})
    for k in range(n):
        warm = k < WARMUP
        if k > 0:
            y[k] = m.get("plant", ["y"])[0]
            v = m.get("compensator", ["v"])[0]
        if lagged is not None and not warm and _invertible(lagged[:2], lagged[2:3]):
            a, b = lagged[:2], lagged[2:3]
        v = r[min(k + d, n - 1)] if warm else v
        acc = v  # in the library's order of operations (adaptive.rs, FeedForward::input)
        for ai, x in zip(a, x_hist):
            acc += ai * x
        for bj, uj in zip(b[1:], u_hist):
            acc -= bj * uj
        uk = acc / b[0]
        x_hist, u_hist = [v] + x_hist[:-1], [uk] + u_hist[:-1]
        f = 1.0 + ramp * k / n
        m.set("plant", {"u": uk, "c1": PAPER["c1"] * f, "c2": PAPER["c2"] * f})
        m.set("estimator", {"u": uk})
        m.step()  # to t_k + Ts/2: the units latch sample k's inputs
        # The estimate after samples 0..k-1 (reported at t_k) is sample k + 1's: for the compensator now, for
        # the linear feed-forward at k + 1.
        current = list(m.get("estimator", LINEAR + BACKLASH))
        m.set("compensator", {"r": r[min(k + 1 + d, n - 1)], **dict(zip(BACKLASH, current[3:]))})
        lagged = current if k > 0 else None
        m.step()  # to t_{k+1}
    status = m.ex.status()
    assert status.current_time == n * NS and status.error_code == 0, status
    return y


def test_the_libcosim_loop_gives_the_library_loops_numbers(plant_fmu, estimator_fmu, compensator_fmu, cli,
                                                           tmp_path):
    n, noise, memory = 3000, 0.02, 500
    path, out = tmp_path / "reference.csv", tmp_path / "loop.csv"
    r = write_reference(path, n)
    args = [cli, "compensate", str(path), "--noise-std", str(noise), "--wear", "ramp", "--wear-ratio", "0.5",
            "--memory", str(memory), "--modes", "adaptive", "--out", str(out), "--json"]
    lib = {lag: json.loads(subprocess.run(args + ["--estimate-lag", str(lag)], capture_output=True, text=True,
                                          check=True).stdout)["modes"]["adaptive"] for lag in (0, 1)}
    lib_y = np.genfromtxt(out, delimiter=",", names=True)["y_adaptive"]  # the last run: lag 1
    y = run_loop(plant_fmu, estimator_fmu, compensator_fmu, r, noise, 0.5, memory)
    worst = float(np.max(np.abs(y[1:] - lib_y[1:])))
    print(f"libcosim vs library loop (estimate lag 1): max |y difference| = {worst:.3e}")
    assert np.array_equal(y[1:], lib_y[1:]), worst
    q = n - n // 4
    last = float(np.sqrt(np.mean((y[q:] - r[q:]) ** 2)))
    assert last == lib[1]["rmse_last_quarter"], (last, lib[1])
    # Not vacuous: the loop compensates (the warm-up alone is far off), and the lag is visible.
    assert last < 0.2 and float(np.sqrt(np.mean((y[1:WARMUP] - r[1:WARMUP]) ** 2))) > 0.5
    assert lib[0]["rmse_last_quarter"] != lib[1]["rmse_last_quarter"]
