#!/usr/bin/env python3
"""Co-simulation Monte Carlo study of BacklashPlant.fmu + MrgiaEstimator.fmu, distributed with Dask.

One task per (plant, SNR, seed): fmpy runs the plant FMU and two MrgiaEstimator FMUs (paper and recommended
settings) over the paper input, and the estimates after each N are returned as tidy rows. By default a
dask.distributed LocalCluster with one worker process per core; --scheduler tcp://host:8786 uses a running
cluster (its workers need dask, fmpy and numpy; the FMUs and the task code are sent to them); --serial runs
in this process. Writes cosim_study.csv (same columns as `backlash study`'s study_runs.csv) and
cosim_study.png (RMSE against N) with --out.

Examples:
    scripts/dask_study.py --seeds 20 --ns 300,1000,3000 --out out/dask
    scripts/dask_study.py --seeds 1000 --plants paper,wide-gaps --snrs 20,43 --scheduler tcp://10.0.0.5:8786
The library is tests/python/cosim_study.py (its docstring describes a run).
"""
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests" / "python"))

import cosim_study  # noqa: E402

if __name__ == "__main__":
    sys.exit(cosim_study.main())
