"""Where a first render's compile goes: numba's compile events, per function compiled.

    d=$(mktemp -d); NUMBA_CACHE_DIR=$d RAYTRACE_LOOP=compiled \
        python3 benchmarks/compile_profile.py render scenes/whitted.toml \
        --width 64 --height 48 -o $d/x.exr -q

Runs ``raytrace`` with the given arguments (an empty ``NUMBA_CACHE_DIR``: everything compiles)
and prints on stderr, per function numba compiled on its own (module.name), its seconds
exclusive of the compiles nested in it, inclusive, the part spent finalizing its library
(``CPUCodeLibrary.finalize``: linking the callees' libraries in, LLVM's module optimization and
machine code) and of that the machine code, the functions its final module defines, and how
many signatures it compiled. A function inlined in numba's IR (``jit.inline``) has no line of
its own: its cost is its caller's. docs/performance.md, "The compiled loop", reads it.
"""

from __future__ import annotations

import collections
import sys
import time

from numba.core import codegen
from numba.core import event as numba_event

from raytrace.cli import main

STACK: list[list] = []
EXCLUSIVE: dict[str, float] = collections.defaultdict(float)
INCLUSIVE: dict[str, float] = collections.defaultdict(float)
FINALIZE: dict[str, float] = collections.defaultdict(float)
EMIT: dict[str, float] = collections.defaultdict(float)
FUNCTIONS: dict[str, int] = collections.defaultdict(int)
SIGNATURES: collections.Counter = collections.Counter()


def name_of(dispatcher) -> str:
    return f"{dispatcher.py_func.__module__.split('.')[-1]}.{dispatcher.py_func.__name__}"


def compiling() -> str:
    """The function whose compile is under way (the innermost)."""
    return name_of(STACK[-1][0]) if STACK else "<none>"


class Compiles(numba_event.Listener):
    def on_start(self, event):
        STACK.append([event.data["dispatcher"], time.perf_counter(), 0.0])

    def on_end(self, event):
        dispatcher, start, nested = STACK.pop()
        seconds = time.perf_counter() - start
        name = name_of(dispatcher)
        INCLUSIVE[name] += seconds
        EXCLUSIVE[name] += seconds - nested
        SIGNATURES[name] += 1
        if STACK:
            STACK[-1][2] += seconds


def timed(method, into: dict[str, float], count: bool = False):
    def wrapper(self):
        start = time.perf_counter()
        method(self)
        into[compiling()] += time.perf_counter() - start
        if count:
            FUNCTIONS[compiling()] += sum(1 for f in self._final_module.functions
                                          if not f.is_declaration)
    return wrapper


def report(wall: float, out=sys.stderr) -> None:
    print(f"wall {wall:.2f} s; compiles {sum(EXCLUSIVE.values()):.2f} s over {len(EXCLUSIVE)} "
          f"functions, {sum(SIGNATURES.values())} signatures; finalize "
          f"{sum(FINALIZE.values()):.2f} s, of which machine code {sum(EMIT.values()):.2f} s",
          file=out)
    print(" excl s  incl s  final s  emit s  funcs  sigs  function", file=out)
    for name in sorted(EXCLUSIVE, key=EXCLUSIVE.get, reverse=True):
        print(f"{EXCLUSIVE[name]:7.2f} {INCLUSIVE[name]:7.2f} {FINALIZE[name]:8.2f} "
              f"{EMIT[name]:7.2f} {FUNCTIONS[name]:6d} {SIGNATURES[name]:5d}  {name}", file=out)


if __name__ == "__main__":
    numba_event.register("numba:compile", Compiles())
    library = codegen.CPUCodeLibrary
    library.finalize = timed(library.finalize, FINALIZE, count=True)
    library._finalize_final_module = timed(library._finalize_final_module, EMIT)
    start = time.perf_counter()
    try:
        main(sys.argv[1:])
    except SystemExit:
        pass
    report(time.perf_counter() - start)
