#!/usr/bin/env python3
"""Import loops between the library's modules, from the paths its source names.

Every `crate::a::b::...` and `super::...` path in src/ (outside src/bin, and outside comments and strings)
is an edge from the file that names it to the file of the longest module prefix of the path, as is a
`use child::...` of a module declared beside it; paths from a module into its own descendants are not (it
declares them and may re-export their items: containment, not import). The files form one graph; collapsing each file to the first
1, 2 or 3 segments of its module path gives the graphs of the rooms (`fmi`, `identify::oe`, ...). A loop is
a strongly connected set of two or more nodes in any of these graphs. The trait-implementation seam of the
FMI core (`impl Fmus for Binary` in src/fmus) is no path, and code that build.rs generates and src/
includes is not read: it names `crate::fmi::vars` from `fmus`, an edge the adapters have anyway.

Usage: python3 scripts/module_loops.py [PREFIX ...]
Prints every loop (only those touching a module path that starts with one of the PREFIXes, e.g. `fmi`,
`identify::oe`, when given) and exits 1 if there is one.
"""

import re
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"


def module_of(path: Path, src: Path = SRC) -> tuple:
    rel = path.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("mod", "lib"):
        parts = parts[:-1]
    return tuple(parts)


def strip(text: str) -> str:
    """The code without comments, string and character literals (kept as blanks)."""
    text = re.sub(r'r#*"(?:.|\n)*?"#*', '""', text)
    text = re.sub(r'"(?:\\.|[^"\\])*"', '""', text)
    text = re.sub(r"'(?:\\.|[^'\\\n])'", "' '", text)
    text = re.sub(r"/\*(?:.|\n)*?\*/", " ", text)
    return re.sub(r"//[^\n]*", "", text)


def expand(prefix: list, body: str) -> list:
    """The paths of a `{...}` use group."""
    out, depth, item = [], 0, ""
    for c in body + ",":
        if c == "," and depth == 0:
            item = item.strip()
            if item:
                m = re.match(r"([\w:]*?)::\s*\{(.*)\}$", item, re.S)
                if m:
                    out += expand(prefix + [s for s in m.group(1).split("::") if s], m.group(2))
                else:
                    out.append(prefix + [s for s in item.split(" as ")[0].split("::") if s])
            item = ""
            continue
        depth += c == "{"
        depth -= c == "}"
        item += c
    return out


def paths_in(code: str) -> list:
    """Every path that starts with `crate`, `super` or a plain `use` segment, as lists of segments."""
    found = []
    for m in re.finditer(r"\buse\s+([^;]+);", code):
        found += expand([], m.group(1).replace("\n", " "))
    for m in re.finditer(r"\b((?:crate|super)(?:::(?:super|\w+))+)", code):
        found.append(m.group(1).split("::"))
    return found


def resolve(segments: list, here: tuple, modules: set):
    """The module a path names (its longest module prefix), or None if it leaves the crate's modules."""
    if segments[0] == "crate":
        base, segments = [], segments[1:]
    elif segments[0] in ("super", "self"):
        base = list(here)
        while segments and segments[0] in ("super", "self"):
            base = base[:-1] if segments[0] == "super" else base
            segments = segments[1:]
    elif tuple(list(here) + [segments[0]]) in modules:
        base = list(here)
    else:
        return None
    best = tuple(base)
    for i in range(len(segments)):
        if tuple(base + segments[: i + 1]) not in modules:
            break
        best = tuple(base + segments[: i + 1])
    return best


def inline_modules(code: str, here: tuple) -> list:
    """(module path, code) of the file's own module and of each inline `mod name { ... }` in it, so that a
    `super` inside `mod tests { ... }` means the file's module."""
    out, spans = [], []
    for m in re.finditer(r"\bmod\s+(\w+)\s*\{", code):
        depth, i = 1, m.end()
        while depth and i < len(code):
            depth += {"{": 1, "}": -1}.get(code[i], 0)
            i += 1
        spans.append((m.start(), i, m.group(1), m.end()))
    rest, last = "", 0
    for start, end, name, body in spans:
        if start < last:
            continue
        rest += code[last:start]
        out.append((here + (name,), code[body : end - 1]))
        last = end
    out.append((here, rest + code[last:]))
    return out


def sccs(nodes: set, edges: dict) -> list:
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(nodes):
        if v not in index:
            visit(v)
    return out


def find_loops(src: Path = SRC) -> list:
    """Every loop of the library under `src`, as (which graph, the modules in it)."""
    files = [p for p in src.rglob("*.rs") if "bin" not in p.relative_to(src).parts]
    modules = {module_of(p, src): p for p in files}
    edges = {}
    known = set(modules)
    for p in files:
        here = module_of(p, src)
        for inner, code in inline_modules(strip(p.read_text()), here):
            for segs in paths_in(code):
                # An inline module's paths are its file's edges (`super` resolved from the inline module).
                to = resolve(segs, inner, known) if segs else None
                # A module's paths into its own descendants are containment (it declares them and may
                # re-export their items), not imports.
                if to is not None and to[: len(here)] != here:
                    edges.setdefault(here, set()).add(to)
    loops = []
    for depth in (None, 1, 2, 3):
        cut = (lambda m: m) if depth is None else (lambda m, d=depth: m[:d])
        g = {}
        for a, bs in edges.items():
            for b in bs:
                if cut(a) != cut(b):
                    g.setdefault(cut(a), set()).add(cut(b))
        for comp in sccs({cut(m) for m in modules}, g):
            if comp not in [c for _, c in loops]:
                loops.append(("files" if depth is None else f"modules, depth {depth}", comp))
    return loops


def program_loops(src: Path = SRC) -> list:
    """Loops between the files of each program under `src/bin/<name>/` (main.rs its root): their `super::` and
    `crate::` paths, and their paths into the library (`backlash::a::...`) whose first module has the name of
    one of the program's own modules: a reader that resolves module names cannot tell the two apart, so the
    program avoids them (src/bin/backlash/structure.rs takes `Structure` from `backlash::api`)."""
    loops = []
    for program in sorted(p for p in (src / "bin").glob("*") if p.is_dir()):
        files = {p.stem: p for p in program.glob("*.rs") if p.stem != "main"}
        edges = {}
        for name, p in files.items():
            code = strip(p.read_text())
            for segs in paths_in(code):
                if len(segs) > 1 and segs[0] in ("super", "crate", "backlash") and segs[1] in files:
                    if segs[1] != name:
                        edges.setdefault((name,), set()).add((segs[1],))
            for m in re.finditer(r"\bbacklash::\{([^;]*)\}", code):
                for segs in expand([], m.group(1)):
                    if segs and segs[0] in files and segs[0] != name:
                        edges.setdefault((name,), set()).add((segs[0],))
        for comp in sccs({(n,) for n in files}, edges):
            loops.append((f"program {program.name}", comp))
    return loops


def main() -> int:
    prefixes = [tuple(p.split("::")) for p in sys.argv[1:]]
    loops = find_loops() + program_loops()
    shown = [
        (what, comp)
        for what, comp in loops
        if not prefixes or any(m[: len(p)] == p for m in comp for p in prefixes)
    ]
    name = lambda m: "::".join(m) or "crate"
    for what, comp in shown:
        print(f"loop ({what}): " + " <-> ".join(name(m) for m in comp))
    if not shown:
        print("no import loop" + (" touching " + ", ".join(map(name, prefixes)) if prefixes else ""))
    return 1 if shown else 0


if __name__ == "__main__":
    sys.exit(main())
