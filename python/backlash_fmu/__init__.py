"""Backlash identification on NumPy arrays, the FMUs as files, and the `backlash` command.

- `fmu_path(name, fmi_version=2)`: the packaged BacklashPlant / MrgiaEstimator / BacklashCompensator FMU (for
  FMPy or any FMI tool).
- `compensate(r, ...)`: the adaptive compensation loop of `backlash compensate`.
- `simulate(u, **params)`: the plant of `backlash simulate`.
- `identify_mrgia`, `identify_oe`, `identify_frequency`, `crb`, `diagnose`: the estimators and the diagnosis,
  returning the JSON object of the matching `backlash ... --json` command as a dict (equal to it on the same
  data; the keys that describe a file, such as `file`, are None here).
- `backlash_fmu.cosim` (FMPy pair master, container FMU) and `backlash_fmu.study` (the Dask study) need the
  `cosim` and `study` extras.

The computations run in Rust with the GIL released. A bad argument (NaN, arrays of different lengths, a
record too short, an order out of range) raises ValueError with the library's message.
"""
import json
import pathlib
import sys
import time

import numpy as np

from . import _backlash

__version__ = _backlash.__version__
__all__ = ["fmu_path", "simulate", "identify_mrgia", "identify_oe", "identify_frequency", "crb", "diagnose",
           "monitor", "compensate", "PLANT_PARAMETERS"]

#: The names `simulate` takes: "a" and "b" (lists), then every parameter of BacklashPlant.fmu, read from its
#: model description.
PLANT_PARAMETERS = tuple(_backlash.plant_parameters())

MODELS = ("BacklashPlant", "MrgiaEstimator", "BacklashCompensator")
_HERE = pathlib.Path(__file__).resolve().parent


def fmu_path(name, fmi_version=2):
    """The path (str) of the FMU `name` ("BacklashPlant", "MrgiaEstimator" or "BacklashCompensator") inside the
    package: FMI 2.0,
    or the FMI 3.0 variant with fmi_version=3."""
    if name not in MODELS:
        raise ValueError(f"unknown FMU {name!r}: the package has {', '.join(MODELS)}")
    folders = {2: "fmu", 3: "fmu3"}
    if fmi_version not in folders:
        raise ValueError(f"fmi_version {fmi_version!r} must be 2 or 3")
    path = _HERE / folders[fmi_version] / f"{name}.fmu"
    if not path.is_file():
        raise FileNotFoundError(
            f"this installation of backlash-fmu has no FMI {fmi_version}.0 {name}.fmu ({path} is missing): "
            + ("it was built before the FMI 3.0 variants existed, or without them"
               if fmi_version == 3 else "it was built without packaging the FMUs (a debug build or BACKLASH_FMU=never)"))
    return str(path)


def _array(x, name):
    """A one-dimensional float64 array (no copy when x already is one)."""
    a = np.ascontiguousarray(x, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional (one value per sample), not of shape {a.shape}")
    return a


def _progress(progress):
    """The one progress protocol of every function with `progress=`: None or False, no progress; True, the bar
    on standard error (`_Bar`); a callable, called as progress(done, total), two numbers (total may grow while
    the work is discovered, as diagnose's rounds are; done never decreases and equals total in the last call of a
    computation that succeeds)."""
    if progress is None or progress is False:
        return None
    if progress is True:
        return _Bar()
    if callable(progress):
        return progress
    raise ValueError("progress must be None, True, False or a callable progress(done, total)")


class _Bar:
    """The progress bar on standard error: tqdm's when it is installed, else a line of text."""

    def __init__(self):
        self._tqdm = None
        self._start = time.monotonic()

    def __call__(self, done, total):
        try:
            from tqdm import tqdm
        except ImportError:
            tqdm = None
        if tqdm is not None:
            if self._tqdm is None:
                self._tqdm = tqdm(total=total)
            if self._tqdm.total != total:
                self._tqdm.total = total
            self._tqdm.update(done - self._tqdm.n)
            if done >= total:
                self._tqdm.close()
            return
        width = 40
        full = width * done // max(total, 1)
        seconds = time.monotonic() - self._start
        sys.stderr.write(f"\r{'#' * full}{'-' * (width - full)} {done}/{total} {seconds:6.1f} s")
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _spec(params):
    """Plant parameters as the library reads them (a dict; unknown names are refused there, by name)."""
    spec = {}
    for k, v in params.items():
        if v is None:
            continue
        if k in ("a", "b"):
            spec[k] = [float(c) for c in np.atleast_1d(v)]
        else:
            spec[k] = v
    return spec


def _result(text, **file_keys):
    out = json.loads(text)
    out.update(file_keys)
    return out


def simulate(u, **params):
    """The plant on the input samples u: {"x": ..., "w": ..., "y": ...} (NumPy arrays, one value per sample).

    params are the plant FMU's parameters by their names (PLANT_PARAMETERS lists them all): a (list
    a1..a_na, which sets na), b (list b0..b_nb, which sets nb), Ts, delay, m1, m2, c1, c2, noise_std,
    noise_seed, and the test bench's effects (c1_rate, noise_phi, quant_step, ...; see docs/INTERFACE.md).
    Unset ones keep the FMU's start values: paper 000's example (a = [0.45, 0.55], b = [0.8], delay 1, m1 1,
    m2 1.5, c1 0.5, c2 1, no noise, Ts 1 s). An unknown name raises ValueError naming it.
    """
    x, w, y = _backlash.simulate(_array(u, "u"), _spec(params))
    return {"x": x, "w": w, "y": y}


def identify_mrgia(u, y, na, nb, delay, recommended=False, *, refine=False, p0=None, rho_exp=None, rho_min=None,
                   eps=None, sigma0=None, c_init=None, progress=None, decimate=1):
    """MRGIA (paper 000) over the record: the dict of `backlash identify mrgia --json`.

    recommended selects the project's on-line setting; refine (the estimator FMU's `refine`) refines on-line to
    the output-error accuracy and adds `std_err`; p0 .. c_init replace single settings. progress: None
    (default), True (a bar on standard error) or a callable progress(done, total). decimate: average blocks of
    that many samples into one first, as the command's --decimate.
    """
    text = _backlash.identify_mrgia(_array(u, "u"), _array(y, "y"), na, nb, delay, recommended, refine, p0,
                                    rho_exp, rho_min, eps, sigma0, c_init, _progress(progress), decimate)
    return _result(text, file=None)


def identify_oe(u, y, na=None, nb=None, delay=None, *, max_delay=10, single_start=False, max_iter=None,
                crb_noise_std=None, target_rel=None, progress=None, decimate=None):
    """The output-error fit with standard errors: the dict of `backlash identify oe --json`. Without na, nb and
    delay the structure is chosen from the data (as the command does). progress: None (default), True (a bar
    on standard error) or a callable progress(done, total), counting stages. decimate: as the command's
    --decimate (None: the rate is chosen from the data, as the command does without it; `rate` says how)."""
    text = _backlash.identify_oe(_array(u, "u"), _array(y, "y"), na, nb, delay, max_delay, single_start,
                                 max_iter, crb_noise_std, target_rel, _progress(progress), decimate)
    return _result(text, file=None)


def identify_frequency(time, u, y, *, omega=None, amplitude=None, degree=None, start=None, end=None,
                       transient=None):
    """Paper 003 on one sine experiment (time in s, omega in rad/s): the dict of `backlash identify frequency
    --json`. u may be None when omega and amplitude are given."""
    text = _backlash.identify_frequency(_array(time, "time"), None if u is None else _array(u, "u"),
                                        _array(y, "y"), omega, amplitude, degree, start, end, transient)
    return _result(text, file=None)


def crb(u, *, noise_std=None, snr=None, target_rel=None, **truth):
    """The Cramer-Rao bound of the output-error model on the input u: the dict of `backlash crb --json`.

    Give noise_std or snr (std(w) / noise std); truth: the plant's a, b, delay, m1, m2, c1, c2 (default: paper
    000's example).
    """
    text = _backlash.crb(_array(u, "u"), _spec(truth), noise_std, snr, target_rel, "array")
    return _result(text)


def diagnose(u, y, na=None, nb=None, delay=None, *, ts=None, max_delay=10, fit_fraction=0.7, seed=0,
             max_effects=3, time_budget=300.0, decimate=None, progress=None):
    """The diagnosis of `backlash diagnose --json` as a dict: the held-out error before and after, and every
    effect the model lacks (`effect` the first, or None).

    Options as the command's: ts (the sample period in s; the command reads it from the time column), max_delay,
    fit_fraction, seed, max_effects, time_budget (s), decimate (average blocks of that many samples into one
    first; orders and delays then count decimated samples; None: the rate is chosen from the data, as the command
    does without --decimate, and `rate` says how). Without na, nb and delay the structure is chosen
    from the data. Without ts the rates and frequencies are per sample only: the keys per second or in Hz
    (c1_rate_per_s, frequency_hz, ...) are left out, and `Ts_note` says so. progress: None (default), True (a
    bar on standard error) or a callable progress(done, total), counting stages and each round's candidates
    (the total grows as a round announces them). `warnings` lists what the record cannot support.
    """
    text = _backlash.diagnose(_array(u, "u"), _array(y, "y"), na, nb, delay, ts, max_delay, fit_fraction, seed,
                              max_effects, time_budget, decimate, _progress(progress))
    return _result(text, file=None, validate_on=[], report=None)


def monitor(u, y, na, nb, delay, wear_ratio=0.1, alarm_period=1e6, *, learn=2000, reference_play=None, ts=1.0,
            recommended=False):
    """The wear monitor of `backlash monitor --json` on the samples: {"alarms": [...], "play": .., "play_se": ..,
    ...} with the times of sample k as k * ts.

    wear_ratio: relative growth of the play c1 + c2 to detect; alarm_period: mean samples between false
    alarms; learn: samples of the refined estimator before the reference is frozen; reference_play: the
    reference play when known; recommended: MRGIA's recommended setting for the warm-up.
    """
    text = _backlash.monitor(_array(u, "u"), _array(y, "y"), na, nb, delay, wear_ratio, alarm_period, learn,
                             reference_play, ts, recommended)
    return _result(text, file=None)


def compensate(r, *, noise_std=0.0, noise_seed=0, wear="none", wear_ratio=0.5, memory=500, smoothing=0.0,
               modes=(), estimate_lag=0):
    """The adaptive compensation loop of `backlash compensate --json` on the reference `r` (the plant output
    wanted at each sample) with the paper plant simulated: {"modes": {"none": {"rmse": ..}, "fixed": ..,
    "adaptive": .., "no-play": ..}, ...}.

    noise_std, noise_seed: the plant's measurement noise; wear: "none", "ramp" (both gaps grow linearly to
    1 + wear_ratio times their start) or "step" (at the middle); memory: the estimator's memory in samples
    (it forgets with rho_min = 1/memory, 0 for none: shorter follows wear faster and is noisier); smoothing:
    the backlash inverse's smoothing half-width (0 = exact); modes: the names to run (empty: all);
    estimate_lag: 0, or 1 for the estimate of the sample before, as a Jacobi master runs the loop
    (`--estimate-lag`).
    """
    text = _backlash.compensate(_array(r, "r"), noise_std, noise_seed, wear, wear_ratio, float(memory),
                                smoothing, list(modes), int(estimate_lag))
    return _result(text, file=None)
