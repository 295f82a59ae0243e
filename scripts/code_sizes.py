#!/usr/bin/env python3
"""Sizes of the house: the longest files, functions and classes of the product's code.

    /usr/bin/python3 scripts/code_sizes.py [--root DIR] [--top N] [--json OUT]

C functions are measured with Universal Ctags (their `end:` field), Python functions and classes
with the `ast` module. The product's code is addon/schnee_probes, native/{src,python,include},
engine/{src,gltf,ext} and the root bake.py; tests, benches and generated files are left out. The
limits of issue 28 (tests/python/test_house.py checks them) are printed with the figures.
"""
from __future__ import annotations

import argparse
import ast
import json
import subprocess
import sys
from pathlib import Path

C_DIRS = ("native/src", "native/python", "native/include", "engine/src", "engine/gltf", "engine/ext")
PY_DIRS = ("addon/schnee_probes",)
PY_FILES = ("bake.py",)
C_SUFFIXES = (".c", ".cpp", ".h")
# Limits (issue 28): C files, add-on classes, the bake driver.
C_FILE_LIMIT = 900
PY_CLASS_LIMIT = 400
DRIVER_LIMIT = 300


def product_files(root: Path):
    c, py = [], []
    for d in C_DIRS:
        for p in sorted((root / d).rglob("*")):
            if p.suffix in C_SUFFIXES and p.is_file() and "test" not in p.parts:
                c.append(p)
    for d in PY_DIRS:
        py += sorted(p for p in (root / d).rglob("*.py") if p.is_file())
    py += [root / f for f in PY_FILES if (root / f).is_file()]
    return c, py


def line_count(p: Path) -> int:
    with open(p, "rb") as f:
        return sum(1 for _ in f)


def c_functions(files):
    """(file, name, lines) of every C function definition, by ctags' start and end lines."""
    if not files:
        return []
    out = subprocess.run(["ctags", "-x", "--_xformat=%F\t%N\t%n\t%{end}", "--kinds-C=f", "--kinds-C++=f",
                          "--fields=+ne", "-o", "-", *map(str, files)],
                         capture_output=True, text=True, check=True).stdout
    rows = []
    for line in out.splitlines():
        parts = line.split("\t")
        if len(parts) == 4 and parts[3].isdigit():
            rows.append((parts[0], parts[1], int(parts[3]) - int(parts[2]) + 1))
    return rows


def py_defs(files, root: Path):
    """(file, kind, name, lines) of every Python class and function (methods as Class.name)."""
    rows = []
    for p in files:
        tree = ast.parse(p.read_text(encoding="utf-8"), str(p))
        rel = str(p.relative_to(root))

        def walk(node, prefix):
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                    kind = "class" if isinstance(child, ast.ClassDef) else "def"
                    name = prefix + child.name
                    rows.append((rel, kind, name, child.end_lineno - child.lineno + 1))
                    walk(child, name + ".")

        walk(tree, "")
    return rows


def report(root: Path, top: int):
    c, py = product_files(root)
    files = sorted(((str(p.relative_to(root)), line_count(p)) for p in c + py), key=lambda r: -r[1])
    cf = sorted(((str(Path(f).relative_to(root)) if Path(f).is_absolute() else f, n, l)
                 for f, n, l in c_functions(c)), key=lambda r: -r[2])
    pd = py_defs(py, root)
    classes = sorted((r for r in pd if r[1] == "class"), key=lambda r: -r[3])
    funcs = sorted((r for r in pd if r[1] == "def"), key=lambda r: -r[3])
    return {
        "files": files[:top],
        "c_files_over_limit": [f for f in files if f[0].endswith(C_SUFFIXES) and f[1] > C_FILE_LIMIT],
        "c_functions": cf[:top],
        "py_classes": [(f, n, l) for f, _, n, l in classes[:top]],
        "py_functions": [(f, n, l) for f, _, n, l in funcs[:top]],
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=str(Path(__file__).resolve().parent.parent))
    ap.add_argument("--top", type=int, default=15)
    ap.add_argument("--json", help="also write the figures to this JSON file")
    a = ap.parse_args(argv)
    r = report(Path(a.root).resolve(), a.top)
    print(f"# longest product files (C limit {C_FILE_LIMIT} lines)")
    for f, n in r["files"]:
        print(f"{n:6d}  {f}")
    print(f"# longest C functions")
    for f, name, n in r["c_functions"]:
        print(f"{n:6d}  {f}: {name}")
    print(f"# longest Python classes (limit {PY_CLASS_LIMIT}; the bake driver {DRIVER_LIMIT})")
    for f, name, n in r["py_classes"]:
        print(f"{n:6d}  {f}: {name}")
    print(f"# longest Python functions")
    for f, name, n in r["py_functions"]:
        print(f"{n:6d}  {f}: {name}")
    if a.json:
        Path(a.json).write_text(json.dumps(r, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
