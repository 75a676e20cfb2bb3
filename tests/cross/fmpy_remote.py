"""One FMPy simulation described by a JSON job, for test_fmpy_remoting.py; run as a script in a process of its
own when FMPy's Wine remoting is used (so that a hung remoting client can be killed from outside):

    python fmpy_remote.py JOB.json OUT.npy

The job: {"fmu", "remote_platform" (null or "win64"), "extract_dir", "stop_time", "start_values", "outputs",
"input": {"time": [...], name: [...]}}. FMPy extracts the FMU into `extract_dir` (Python's tempfile); the
remoting client's lock file goes where the C library's tempnam() puts it (TMPDIR), which the caller sets apart.
"""
import json
import sys
import tempfile

import numpy as np


def simulate(job):
    """simulate_fmu on the job; the result as a structured array (time and the outputs)."""
    from fmpy import simulate_fmu

    tempfile.tempdir = job["extract_dir"]
    columns = job["input"]
    names = list(columns)
    inputs = np.array(list(zip(*(columns[n] for n in names))), dtype=[(n, np.float64) for n in names])
    return simulate_fmu(job["fmu"], remote_platform=job["remote_platform"], stop_time=job["stop_time"],
                        output_interval=1, start_values=job["start_values"], input=inputs, output=job["outputs"])


if __name__ == "__main__":
    with open(sys.argv[1]) as f:
        result = simulate(json.load(f))
    np.save(sys.argv[2], result)
