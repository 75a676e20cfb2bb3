"""The library has no import loop between its modules (scripts/module_loops.py, which reads every file's
`crate::`, `super::` and child paths, test modules included), and the script does find a loop when there is
one."""
import subprocess
import sys

from conftest import ROOT

SCRIPT = ROOT / "scripts" / "module_loops.py"


def test_the_library_has_no_import_loop():
    run = subprocess.run([sys.executable, str(SCRIPT)], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "no import loop" in run.stdout


def test_a_loop_is_found(tmp_path):
    src = tmp_path / "src"
    (src / "a").mkdir(parents=True)
    (src / "lib.rs").write_text("pub mod a;\npub mod b;\n")
    (src / "a" / "mod.rs").write_text("use crate::b::f;\npub fn g() {}\n")
    (src / "b.rs").write_text("pub fn f() { crate::a::g() }\n")
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import module_loops
    finally:
        sys.path.pop(0)
    assert module_loops.find_loops(src) == [("files", [("a",), ("b",)])]
    (src / "b.rs").write_text("pub fn f() {}\n")
    assert module_loops.find_loops(src) == []


def test_a_program_loop_through_a_library_path_of_the_same_name_is_found(tmp_path):
    """A program file naming `backlash::diagnose::...` reads, to a reader resolving module names, as an import
    of the program's own `diagnose` module (the loop src/bin/backlash had between diagnose.rs and
    structure.rs); the program as it is has none."""
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import module_loops
    finally:
        sys.path.pop(0)
    assert module_loops.program_loops() == []
    prog = tmp_path / "src" / "bin" / "prog"
    prog.mkdir(parents=True)
    (prog / "main.rs").write_text("mod diagnose;\nmod structure;\n")
    (prog / "diagnose.rs").write_text("use super::structure::Args;\n")
    (prog / "structure.rs").write_text("use backlash::diagnose::structure::Structure;\n")
    assert module_loops.program_loops(tmp_path / "src") == [("program prog", [("diagnose",), ("structure",)])]
    (prog / "structure.rs").write_text("use backlash::api::Structure;\n")
    assert module_loops.program_loops(tmp_path / "src") == []
