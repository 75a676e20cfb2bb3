"""What an FMI tool shows of each built FMU besides its variables: the example of documentation/index.html runs
as written (FMPy, in the FMU's folder), and FMPy's validation reports nothing with the documentation and the
icon inside (tests/fmu_contents.rs checks that every variable is documented and that the icon decodes)."""
import contextlib
import html
import io
import os
import re
import shutil
import zipfile

import pytest
from fmpy.validation import validate_fmu

from conftest import FMU3_DIR, FMU_DIR

FMUS = sorted(FMU_DIR.glob("*.fmu")) + sorted(FMU3_DIR.glob("*.fmu"))


def test_the_build_left_fmus():
    assert len(FMUS) >= 4, f"run `cargo build --release` first: {FMUS}"


@pytest.mark.parametrize("fmu", FMUS, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_the_documented_example_runs(fmu, tmp_path):
    page = zipfile.ZipFile(fmu).read("documentation/index.html").decode()
    code = html.unescape(re.search(r'<pre class="example"><code>(.*?)</code></pre>', page, re.S).group(1))
    shutil.copy(fmu, tmp_path / fmu.name)
    out = io.StringIO()
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        with contextlib.redirect_stdout(out):
            exec(compile(code, "index.html example", "exec"), {})
    finally:
        os.chdir(cwd)
    assert out.getvalue().strip(), "the example printed nothing"


@pytest.mark.parametrize("fmu", FMUS, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_fmpy_validates_the_fmu(fmu):
    assert validate_fmu(str(fmu)) == []
