"""Package BacklashPlant.fmu and MrgiaEstimator.fmu as ONE co-simulation FMU (fmpy.container_fmu).

The container has one input `u` (driving the plant and the estimator), the plant output `y` (also wired to
the estimator's `y`), and the estimates a1, a2, b0, m2, c1, c2 and `updating`; its step is one sample (Ts = 1).
It is the single file to drop into another FMI tool.

Usage: python scripts/make_pair_container.py [OUTPUT.fmu]   (default target/fmu/BacklashPair.fmu)
"""
import pathlib
import sys
import tempfile

from fmpy.validation import validate_fmu

from backlash_fmu.cosim import build_container

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    out = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "target" / "fmu" / "BacklashPair.fmu"
    fmus = ROOT / "target" / "fmu"
    with tempfile.TemporaryDirectory() as d:
        build_container(fmus / "BacklashPlant.fmu", fmus / "MrgiaEstimator.fmu", pathlib.Path(d) / "unzipped", out)
    problems = validate_fmu(str(out))
    if problems:
        sys.exit(f"{out}: validation found problems: {problems}")
    print(f"wrote {out} (validated)")


if __name__ == "__main__":
    main()
