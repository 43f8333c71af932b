"""The package's layout (docs/architecture.md): a module's dependencies stand at its head, the
import graph has no circle, the compiled kernels import nothing outside their folder, and
``import raytrace`` loads no compiler.

The graph is read from the source (every ``import`` statement, those inside functions
included), not from a run, so a circle that only closes on some code path is found too.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import raytrace
from raytrace.kernels import records

PACKAGE = Path(raytrace.__file__).resolve().parent
#: The two lazy boundaries (docs/architecture.md, "Imports"): the command line's front door
#: and the package's ``__init__`` (PEP 562 ``__getattr__``). Everywhere else a module imports
#: the package's modules at its head.
LAZY_BOUNDARIES = {"raytrace", "raytrace.cli"}
#: What a compiled kernel module may import besides its own folder.
KERNEL_IMPORTS = {"__future__", "math", "numpy", "numba", "llvmlite", "hashlib", "importlib",
                  "os", "re", "sys", "tempfile", "threading", "collections", "contextlib",
                  "pathlib", "typing", "time", "fcntl"}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imports(name: str) -> list[tuple[str, bool, int]]:
    """(imported module, inside a function, line) for every import of ``name``'s source;
    a package-internal ``from X import y`` names the module ``X.y`` where that is one."""
    path = MODULES[name]
    tree = ast.parse(path.read_text("utf-8"))
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = []

    def visit(node: ast.AST, inside: bool) -> None:
        for child in ast.iter_child_nodes(node):
            nested = inside or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                  ast.Lambda))
            if isinstance(child, ast.Import):
                found.extend((a.name, inside, child.lineno) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package[:len(package) - child.level + 1]
                    module = ".".join(base + ([child.module] if child.module else []))
                else:
                    module = child.module or ""
                subs = [f"{module}.{a.name}" for a in child.names if f"{module}.{a.name}" in
                MODULES]
                found.extend((m, inside, child.lineno) for m in (subs or [module]))
            visit(child, nested)

    visit(tree, False)
    return found


def test_package_modules_are_imported_at_the_head_outside_the_two_lazy_boundaries():
    inner = [f"{name}:{line} imports {target}" for name in MODULES for target, inside, line
             in imports(name) if inside and target in MODULES and name not in LAZY_BOUNDARIES]
    assert inner == []


def test_the_import_graph_has_no_circle():
    graph = {name: {t for t, _, _ in imports(name) if t in MODULES and t != name}
             for name in MODULES}
    done: set[str] = set()

    def walk(name: str, path: list[str]) -> None:
        if name in path:
            raise AssertionError("import circle: " + " -> ".join(path[path.index(name):] + [name]))
        if name in done:
            return
        for target in sorted(graph[name]):
            walk(target, [*path, name])
        done.add(name)

    for name in MODULES:
        walk(name, [])


def test_the_kernels_import_nothing_outside_their_folder():
    outside = [f"{name}:{line} imports {target}" for name in MODULES
               if name.startswith("raytrace.kernels") for target, _, line in imports(name)
               if not target.startswith("raytrace.kernels")
               and target.split(".")[0] not in KERNEL_IMPORTS]
    assert outside == []


def test_import_raytrace_loads_neither_numba_nor_numpy_s_users_of_it():
    # The package's __init__ names its API lazily (PEP 562): the compiler, Embree and the
    # renderer load when first used.
    code = ("import sys, raytrace; raytrace.__all__; "
            "print(sorted(m for m in ('numba', 'embreex', 'raytrace.integrator', "
            "'raytrace.kernels.jit') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


def test_every_name_the_package_exports_resolves():
    for name in raytrace.__all__:
        assert getattr(raytrace, name) is not None, name


def test_every_registered_record_is_exported_by_its_class_name(monkeypatch):
    # A light or object record is exported by the line that registers it: raytrace's
    # __getattr__, __all__ and __dir__ read lights.LIGHT_TYPES and scene.OBJECT_TYPES.
    from raytrace.lights import LIGHT_TYPES
    from raytrace.scene import OBJECT_TYPES

    for cls in (*LIGHT_TYPES.values(), *OBJECT_TYPES.values()):
        assert getattr(raytrace, cls.__name__) is cls
        assert cls.__name__ in raytrace.__all__ and cls.__name__ in dir(raytrace)

    class LineLight:  # a light registered after import is found too
        type = "line"

    monkeypatch.setitem(LIGHT_TYPES, "line", LineLight)
    try:
        assert raytrace.LineLight is LineLight
        assert "LineLight" in raytrace.__all__
    finally:
        vars(raytrace).pop("LineLight", None)  # what __getattr__ kept
    monkeypatch.delitem(LIGHT_TYPES, "line")
    with pytest.raises(AttributeError, match="has no attribute 'LineLight'"):
        raytrace.LineLight  # noqa: B018


def test_a_hits_material_is_looked_up_in_one_place():
    # Colour, checker, texture, texture coordinates and opacity are read by the material
    # lookup of kernels/material.py alone; every kernel and explain call its two functions.
    pieces = {"color1", "texel1", "texcoord1", "opacity1"}
    calls = []
    for name, path in MODULES.items():
        if name == "raytrace.kernels.material":
            continue
        for node in ast.walk(ast.parse(path.read_text("utf-8"))):
            if isinstance(node, ast.Call):
                f = node.func
                called = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
                if called in pieces:
                    calls.append(f"{name}:{node.lineno} {called}")
    assert calls == []
    users = {name for name, path in MODULES.items()
             if "surface_color1(" in path.read_text("utf-8")} - {"raytrace.kernels.material"}
    assert {"raytrace.kernels.shading", "raytrace.kernels.aov", "raytrace.raytree"} <= users


# -- the kernels read named records (STYLE.md point 9; pbrt-v4's workitems.soa) -------------
KERNELS = PACKAGE / "kernels"
#: The most inputs a kernel reads (docs/architecture.md, "No kernel reads more than eight
#: inputs").
MOST_INPUTS = 8


def kernel_functions() -> list[tuple[str, ast.FunctionDef]]:
    """Every function decorated ``@kernel`` or ``@inline`` in ``kernels/*.py``, and every
    module function an ``@overload`` returns as its implementation (numba compiles it as a
    kernel), as ``("module.py:name", node)``."""
    found = []
    for path in sorted(KERNELS.glob("*.py")):
        body = ast.parse(path.read_text("utf-8")).body
        functions = {n.name: n for n in body if isinstance(n, ast.FunctionDef)}
        returned = {name.id for n in functions.values()
                    if any(isinstance(d, ast.Call) and getattr(d.func, "id", "") == "overload"
                           for d in n.decorator_list)
                    for r in ast.walk(n) if isinstance(r, ast.Return) and r.value is not None
                    for name in ast.walk(r.value) if isinstance(name, ast.Name)}
        for node in functions.values():
            if any(getattr(d, "id", "") in ("kernel", "inline") for d in node.decorator_list) \
                    or node.name in returned:
                found.append((f"{path.name}:{node.name}", node))
    return found


def unpacked(fn: ast.FunctionDef) -> dict[str, list[list[str]]]:
    """Each parameter the body unpacks by position (``a, b, c = param``): the targets of
    every such unpacking, as source text."""
    params = {a.arg for a in fn.args.args}
    found: dict[str, list[list[str]]] = {}
    for node in ast.walk(fn):
        if (isinstance(node, ast.Assign) and isinstance(node.value, ast.Name)
                and node.value.id in params and isinstance(node.targets[0], ast.Tuple)):
            found.setdefault(node.value.id, []).append(
                [ast.unparse(e) for e in node.targets[0].elts])
    return found


def inputs(fn: ast.FunctionDef) -> int:
    """How many inputs a kernel reads: one per parameter, except a parameter unpacked by
    position, which counts as many as the names it is unpacked into (a named record read by
    attribute, ``rays.origin``, counts one)."""
    count = {a.arg: 1 for a in fn.args.args}
    for param, targets in unpacked(fn).items():
        count[param] = max(count[param], *(len(t) for t in targets))
    return sum(count.values())


def test_no_kernel_reads_more_than_eight_inputs():
    # A kernel reads a few named records, not twenty values in a row (STYLE.md point 9).
    over = {name: inputs(fn) for name, fn in kernel_functions() if inputs(fn) > MOST_INPUTS}
    assert over == {}


def test_no_kernel_unpacks_a_record_by_position():
    # A record's fields are read by name (``hits.t``), never as ``t, shape, … = hits``, whose
    # order a new field would silently shift. From the source, a parameter unpacked by
    # position is taken for a record of kernels/records.py where its names are one record's
    # fields, as many and at least half of them that record's (a prefix such as ``s_``
    # aside), or where it has more than four names or nests tuples: the plain tuples a
    # kernel unpacks are points, directions and colours (3) and the four corners of a cell.
    fields = [cls._fields for cls in vars(records).values()
              if isinstance(cls, type) and issubclass(cls, tuple) and hasattr(cls, "_fields")]
    assert len(fields) > 10

    def is_record(names: list[str]) -> bool:
        if len(names) > 4 or any(n.startswith("(") for n in names):  # long, or nested
            return True
        return any(len(f) == len(names) and 2 * sum(
            n in f or n.split("_", 1)[-1] in f for n in names) >= len(names) for f in fields)

    assert is_record(["t", "shape", "triangle", "uv"])             # = hits (Hits)
    assert is_record(["rows", "s_origin", "s_direction", "s_tmax", "s_shape"])  # Shadows
    assert is_record(["origin", "direction"])                       # = ray (Ray)
    assert not is_record(["px", "py", "pz"]) and not is_record(["r0", "r1", "r2", "r3"])
    found = [f"{name}: {', '.join(t)} = {param}" for name, fn in kernel_functions()
             for param, targets in unpacked(fn).items() for t in targets if is_record(t)]
    assert found == []
