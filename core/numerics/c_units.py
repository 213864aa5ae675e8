"""Translation units of bounded size, compiled in parallel on the machine's cores.

A long tape is printed as functions of bounded size (:func:`lagrangian.tape.c_body`); those functions are
grouped into units, each between the lines :data:`BEGIN` and :data:`END` of the library's one source.  The
source stays one valid C file (an FMU ships it so, and the cache keys it whole).  To build it, :func:`split`
cuts it into the main unit (everything outside the markers, with the functions' prototypes) and the units, and
:class:`Compilation` compiles them to objects side by side, at most one compiler per core, then links them.

Measured on 2 cores, GCC -O3, ``compile_model(numeric, "native")`` on an empty cache: the native
library of 30 bodies on spherical joints (2.8 MB of C) takes 6.75 s of wall time as one unit and 3.76 s in units
of 4 parts (3.65 s of 8, 4.03 s of 2), for 6.5 and 6.7 s of compiler CPU; 100 planar links, 4.48 s and 2.55 s.

>>> source = "int main_unit;\\n" + BEGIN + "\\n" + "int part_0;\\n" + END + "\\n" + "int after;\\n"
>>> [unit.splitlines()[-1] for unit in split(source)]
['int after;', 'int part_0;']
"""

from __future__ import annotations

import os
import subprocess
import time
from collections.abc import Callable, Sequence
from pathlib import Path

__all__ = ["BEGIN", "END", "PART", "PREAMBLE", "UNIT_PARTS", "Compilation", "split"]

#: The lines that open and close a unit of its own in a library's source.
BEGIN, END = "/* lagrangian: unit */", "/* lagrangian: end of unit */"
#: How a part function is declared: not inlined (it stays a function of bounded size), visible to the other units
#: of its library and to nothing else.
PART = "LG_PART"
#: What every unit starts with (and, being idempotent, may repeat inside the one source).
PREAMBLE = """#include <math.h>
#ifndef LG_PART
#if defined(__GNUC__) && !defined(_WIN32)
#define LG_PART __attribute__((noinline, visibility("hidden")))
#elif defined(__GNUC__)
#define LG_PART __attribute__((noinline))
#else
#define LG_PART
#endif
#endif"""
#: Parts (of :data:`lagrangian.tape.C_PART` instructions) per unit: 4, about a second of GCC -O3 each.  Smaller
#: units pay the compiler's start and the preamble more often; larger ones leave cores idle at the end.
UNIT_PARTS = 4


def split(source: str) -> list[str]:
    """The main unit of ``source`` (its lines outside :data:`BEGIN` … :data:`END`), then each unit."""
    main: list[str] = []
    units: list[list[str]] = []
    inside = False
    for line in source.split("\n"):
        if line == BEGIN and not inside:
            inside = True
            units.append([])
        elif line == END and inside:
            inside = False
        else:
            (units[-1] if inside else main).append(line)
    return ["\n".join(main)] + ["\n".join(unit) + "\n" for unit in units]


class Compilation:
    """Compile ``units`` (written to ``work``) into the shared library ``out``: every unit to an object, at most
    ``workers`` compilers at a time, then one link (:meth:`start`).  It answers as :class:`subprocess.Popen` does where the
    cache's builder asks (``poll``, ``communicate``, ``kill``, ``returncode``), so one library built in units is
    started, awaited and abandoned as one built in one piece is.  ``write(path, data)`` writes each unit's source.
    """

    def __init__(self, cc: str, flags: Sequence[str], units: Sequence[str], work: Path, out: Path,
                 workers: int | None = None, write: Callable[[Path, bytes], object] = Path.write_bytes):
        compile_flags = [f for f in flags if f != "-shared"]
        self._work = work
        self._pending: list[list[str]] = []
        objects = []
        for k, text in enumerate(units):
            src, obj = work / f"unit{k}.c", work / f"unit{k}.o"
            write(src, text.encode())
            self._pending.append([cc, *compile_flags, "-c", "-o", str(obj), str(src)])
            objects.append(str(obj))
        self._link: list[str] | None = [cc, *flags, "-o", str(out), *objects, "-lm"]
        self._workers = max(1, workers or os.cpu_count() or 1)
        self._running: dict[subprocess.Popen, Path] = {}
        self._started = 0
        self._error = ""
        self.returncode: int | None = None

    def start(self) -> Compilation:
        """Start the first compilers (OSError when the compiler cannot be run)."""
        self._launch()
        return self

    def _launch(self) -> None:
        if not self._pending and not self._running and self._link is not None:
            self._pending, self._link = [self._link], None  # every object is written: link them
        while self._pending and len(self._running) < self._workers:
            log = self._work / f"compiler{self._started}.err"  # (a file: a pipe nobody reads would fill)
            self._started += 1
            with open(log, "w", encoding="utf-8") as err:
                proc = subprocess.Popen(self._pending.pop(0), stdout=subprocess.DEVNULL, stderr=err)
            self._running[proc] = log
        if not self._running and self.returncode is None:
            self.returncode = 0

    def poll(self) -> int | None:
        for proc in [p for p in self._running if p.poll() is not None]:
            log = self._running.pop(proc)
            if proc.returncode and self.returncode is None:
                self._error = log.read_text(encoding="utf-8", errors="replace")
                self.returncode = proc.returncode
                self.kill()
        if self.returncode is None:
            self._launch()
        return self.returncode

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        """Wait until the library is linked or a compiler fails; ``("", its errors)``.  Raises
        :class:`subprocess.TimeoutExpired` past ``timeout`` seconds, the compilers left running."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                raise subprocess.TimeoutExpired(self._link or "cc", timeout or 0.0)
            try:  # (woken when the first finishes; the others are polled then too)
                next(iter(self._running)).wait(timeout=0.05 if left is None else min(0.05, left))
            except subprocess.TimeoutExpired:
                pass
        return "", self._error

    def kill(self) -> None:
        """Stop every compiler still running (a failure elsewhere, an interrupt, a timeout)."""
        self._pending, self._link = [], None
        for proc in self._running:
            if proc.poll() is None:
                proc.kill()
        for proc in self._running:
            proc.wait()
        self._running.clear()
        if self.returncode is None:
            self.returncode = -9
