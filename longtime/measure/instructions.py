"""A deterministic cost: the instructions an integration executes, counted by Valgrind's
Callgrind (Debian package ``valgrind``).

What is counted is chosen from inside the process, by Valgrind client requests: the magic
instruction sequence of ``valgrind.h`` (amd64), compiled once with llvmlite into a tiny
function that ctypes calls. Callgrind starts with instrumentation and collection off
(``--instr-atstart=no --collect-atstart=no``), so importing Python, numpy and numba and
loading the compiled kernels run uninstrumented (fast) and uncounted; ``counted_call``
switches collection on around exactly one call into a compiled loop, and ``dump(label)``
writes the count of one cell to a file of its own (and zeroes it for the next cell).

Why client requests and not ``--toggle-collect=<symbol>``: numba's kernels are machine code
that LLVM emits into anonymous memory, with no symbol table Valgrind can read, so a toggle
on the kernel's name never fires; ``callgrind_control`` acts asynchronously, between
Valgrind's scheduling slices, so where it starts and stops counting moves from run to run.
A client request is an instruction of the program itself: the count starts and stops at the
same instruction in every run. What lies between the two requests besides the kernel is
numba's dispatch of the call (unboxing the arguments, boxing the returned tuple) and the
ctypes calls of the two requests: C code only, no Python instruction the interpreter
specialises (``counted_call``), with the garbage collector off and Python's objects from
the C allocator (longtime.execution.valgrind), so the count of a cell does not depend on the
cells counted before it in the same process. What still moves it is the path the
allocators take: identical code counted in any batch agrees within ``COUNT_NOISE``.

This module runs in the process Valgrind executes (``longtime.execution.valgrind``); in a
process without Valgrind the requests are no-ops (``running()`` is 0).
"""
from __future__ import annotations

import ctypes
import functools
import gc
import os
import platform
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any, Callable, Iterable

from longtime.core.params import InputError

DEBIAN_PACKAGE = "valgrind"
# Callgrind's client requests (valgrind/callgrind.h: VG_USERREQ_TOOL_BASE('C', 'T') + n)
_CT = (ord("C") << 24) | (ord("T") << 16)
DUMP_STATS_AT, ZERO_STATS, TOGGLE_COLLECT = _CT + 3, _CT + 1, _CT + 2
START_INSTRUMENTATION, STOP_INSTRUMENTATION = _CT + 4, _CT + 5
RUNNING_ON_VALGRIND = 0x1001  # valgrind.h's core request
# how much slower than the timed run a kernel may run under Callgrind (measured 5x to 50x;
# the high end, for an estimate that must not underrate a cell)
SLOWDOWN = 50.0
# the arguments every Callgrind process of longtime runs with: nothing instrumented or
# counted until the client requests say so; no cache or branch simulation (the count of
# instructions, Ir, is all that is read)
# how closely counts of identical code agree, counted in any batch, process or order and
# beside any load (docs/machines.md, "What can still move a count"): within this many
# instructions a call into the compiled loop (measured: at most 52, the paths of glibc's
# free and of the dispatch's C calls), whatever the cell's size
COUNT_NOISE = 100
# what the counts of a row were taken with: Valgrind's tool and version (tool_version), the
# way a call is counted (``counted_call``) and the target the kernels were compiled for;
# counts of another are not compared
COUNT_METHOD = "the calls alone"
CALLGRIND_OPTIONS = ("--tool=callgrind", "--instr-atstart=no", "--collect-atstart=no",
                     "--cache-sim=no", "--branch-sim=no", "--dump-instr=no", "--compress-strings=no")


def count_factor(factor: float, counts: Iterable[int]) -> float:
    """The ratio two counts of one cell must pass to be a change of the code: ``factor``, or
    more where COUNT_NOISE is a larger share of the smallest of ``counts`` (a cell of a few
    steps, whose count is mostly the dispatch of the call)."""
    smallest = min(counts, default=0)
    return max(factor, 1 + COUNT_NOISE / smallest) if smallest > 0 else factor


def valgrind_path() -> str | None:
    """The valgrind executable on PATH, or None."""
    return shutil.which("valgrind")


def require() -> str:
    """The valgrind executable, or InputError (one line naming the Debian package)."""
    path = valgrind_path()
    if path is None:
        raise InputError(f"counting instructions (--cost instructions) needs Valgrind, which is not on PATH: "
                         f"install the Debian package '{DEBIAN_PACKAGE}' (apt-get install {DEBIAN_PACKAGE})")
    if platform.machine() not in ("x86_64", "AMD64"):
        raise InputError(f"--cost instructions counts with Valgrind client requests written for x86-64 (amd64); "
                         f"this machine is {platform.machine()}: count on an x86-64 machine (the count is the same "
                         f"on every one: docs/machines.md) and bring its store here with `longtime merge`")
    return path


@functools.lru_cache(maxsize=1)
def tool_version() -> str:
    """'callgrind <valgrind version>': counts of different Valgrind versions are not compared
    blindly (the row stores it)."""
    path = valgrind_path()
    if path is None:
        return "callgrind"
    try:
        out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        out = ""
    return f"callgrind {out.removeprefix('valgrind-') or 'unknown'}"


@functools.lru_cache(maxsize=1)
def _request_function():
    """``request(code, a1..a5) -> result``: valgrind.h's VALGRIND_DO_CLIENT_REQUEST for amd64
    (the six words in memory, their address in rax, the rotations of rdi that spell the
    request, ``xchg rbx, rbx``; the result comes back in rdx, which holds the default 0 when
    no Valgrind runs the process), compiled by LLVM (numba's llvmlite)."""
    import llvmlite.binding as llvm
    import llvmlite.ir as ir

    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    llvm.initialize_native_asmparser()  # LLVM parses the inline assembly
    i64, i32 = ir.IntType(64), ir.IntType(32)
    module = ir.Module(name="longtime_valgrind_request")
    fn = ir.Function(module, ir.FunctionType(i64, [i64] * 6), name="longtime_valgrind_request")
    b = ir.IRBuilder(fn.append_basic_block())
    words = b.alloca(ir.ArrayType(i64, 6))
    for i, arg in enumerate(fn.args):
        b.store(arg, b.gep(words, [ir.Constant(i32, 0), ir.Constant(i32, i)]))
    magic = ir.InlineAsm(ir.FunctionType(i64, [i64, i64]),
                         "rolq $$3, %rdi ; rolq $$13, %rdi\n\trolq $$61, %rdi ; rolq $$51, %rdi\n\txchgq %rbx,%rbx",
                         "={dx},{ax},0,~{cc},~{memory},~{dirflag},~{fpsr},~{flags}", side_effect=True)
    b.ret(b.call(magic, [b.ptrtoint(words, i64), ir.Constant(i64, 0)]))
    target = llvm.Target.from_default_triple().create_target_machine()
    parsed = llvm.parse_assembly(str(module))
    parsed.verify()
    engine = llvm.create_mcjit_compiler(parsed, target)
    engine.finalize_object()
    address = engine.get_function_address("longtime_valgrind_request")
    request = ctypes.CFUNCTYPE(ctypes.c_uint64, *[ctypes.c_uint64] * 6)(address)
    request.engine = engine  # the code lives as long as the engine
    return request


def request(code: int, arg: int = 0) -> int:
    return int(_request_function()(code, arg, 0, 0, 0, 0))


def running() -> int:
    """How many Valgrinds run this process (0: none)."""
    return request(RUNNING_ON_VALGRIND)


def begin_cell() -> None:
    """Instrument from here on (the kernel is loaded and warmed up) and zero the count. The
    garbage collector is off until ``dump``: a collection that falls inside a counted call
    would count the objects of everything that ran before it."""
    gc.collect()
    gc.disable()
    request(START_INSTRUMENTATION)
    request(ZERO_STATS)


@functools.lru_cache(maxsize=1)
def _toggle() -> Callable[[], int]:
    """The request TOGGLE_COLLECT as one call into C: the ctypes function with its arguments
    bound (functools.partial), so no Python line runs between it and what it brackets."""
    return functools.partial(_request_function(), TOGGLE_COLLECT, 0, 0, 0, 0, 0)


def counted_call(fn: Callable[..., Any], args: tuple) -> Any:
    """``fn(*args)`` with collection on for the call alone: between the two requests run
    only the call's dispatch into ``fn`` (numba's, for a compiled loop) and ``fn`` itself.
    Every call here is written ``f(*args)`` (CALL_FUNCTION_EX, which the interpreter never
    specialises): a plain call's instruction is specialised, or its specialisation retried,
    at a moment that depends on how often it ran before, which would move the count of one
    cell with the cells counted before it."""
    toggle = _toggle()
    toggle(*())  # a constant: no global looked up (LOAD_GLOBAL is specialised too)
    try:
        return fn(*args)
    finally:
        toggle(*())


def dump(label: str) -> None:
    """Write the count since ``begin_cell`` to a dump file whose description ends in
    ``label``, zero it, stop instrumenting (the next cell's loading runs fast) and turn the
    garbage collector back on."""
    text = ctypes.create_string_buffer(label.encode())
    request(DUMP_STATS_AT, ctypes.addressof(text))
    request(STOP_INSTRUMENTATION)
    end_cell()


def end_cell() -> None:
    """Turn the garbage collector back on after a cell (``dump`` does; a process that counts
    nothing, outside Valgrind, calls this instead)."""
    gc.enable()


_TRIGGER = re.compile(r"^desc: Trigger: Client Request: (.*)$", re.M)
_TOTALS = re.compile(r"^(?:totals|summary):\s+(\d+)", re.M)


def read_dumps(prefix: str | os.PathLike) -> dict[str, int]:
    """Instructions (Ir) by label from the dump files ``<prefix>.<n>`` that ``dump`` wrote."""
    prefix = Path(prefix)
    found: dict[str, int] = {}
    for path in sorted(prefix.parent.glob(prefix.name + ".*")):
        text = path.read_text(errors="replace")
        label, total = _TRIGGER.search(text), _TOTALS.search(text)
        if label and total:
            found[label.group(1).strip()] = int(total.group(1))
    return found


def command(valgrind: str, out_prefix: str | os.PathLike) -> list[str]:
    """The Valgrind part of the command line of a counting process."""
    return [valgrind, *CALLGRIND_OPTIONS, f"--callgrind-out-file={out_prefix}", "-q"]


# The CPU the counted kernels are compiled for, whatever the host: x86-64-v3 (the x86-64
# psABI level of Haswell: AVX2, FMA, BMI1/2, F16C, LZCNT, MOVBE), every instruction of which
# Valgrind runs, with its features spelled out (numba otherwise adds the host's own, AVX-512
# among them). The same kernels on every x86-64 host give the same count.
COUNT_TARGET = "x86-64-v3"
COUNT_TARGET_FEATURES = ("+64bit,+cmov,+cx8,+fxsr,+mmx,+sse,+sse2,+cx16,+sahf,+popcnt,+sse3,+ssse3,+sse4.1,"
                         "+sse4.2,+avx,+avx2,+bmi,+bmi2,+f16c,+fma,+lzcnt,+movbe,+xsave")
# settings that change the code numba compiles: the counting process runs without them
_CODE_SETTINGS = ("NUMBA_OPT", "NUMBA_LOOP_VECTORIZE", "NUMBA_SLP_VECTORIZE", "NUMBA_ENABLE_AVX",
                  "NUMBA_DISABLE_JIT", "NUMBA_BOUNDSCHECK", "NUMBA_DEBUGINFO")
# the packages whose version can move a count of the same code, cell and target
COUNT_PACKAGES = ("numba", "llvmlite", "numpy")


def target_cache_dir() -> Path:
    """The numba cache of the counted kernels: a folder of its own per target, inside the
    host's ($NUMBA_CACHE_DIR, else the cache folder's ``kernels``, where ``longtime cache``
    sees and clears it), so the host's kernels and the counted ones never replace each other."""
    from longtime.core.cache import cache_root

    base = Path(os.environ.get("NUMBA_CACHE_DIR") or cache_root() / "kernels")
    return base / f"counted-{COUNT_TARGET}"


def numba_target_environment() -> dict[str, str]:
    """The environment of the processes that compile and count the kernels: NUMBA_CPU_NAME
    and NUMBA_CPU_FEATURES of the fixed target (COUNT_TARGET), whatever the host's (and its
    NUMBA_CPU_NAME) are, and its own numba cache. Valgrind presents a CPU of its own, and
    numba keys its disk cache by the CPU: with these the kernels compiled beforehand, outside
    Valgrind, are the ones loaded under it."""
    return {"NUMBA_CPU_NAME": COUNT_TARGET, "NUMBA_CPU_FEATURES": COUNT_TARGET_FEATURES,
            "NUMBA_CACHE_DIR": str(target_cache_dir())}


def counting_environment(base: dict[str, str] | None = None) -> dict[str, str]:
    """``base`` (default: this process's environment) with the fixed target's settings, and
    without the settings that would change the code compiled for it."""
    env = {k: v for k, v in (os.environ if base is None else base).items() if k not in _CODE_SETTINGS}
    return {**env, **numba_target_environment()}


@functools.lru_cache(maxsize=1)
def count_versions() -> dict[str, str | None]:
    """The versions that can move a count of the same code, cell and target: Python's,
    numba's and LLVM's (llvmlite), numpy's."""
    from importlib.metadata import PackageNotFoundError, version

    found: dict[str, str | None] = {"python": platform.python_version()}
    for name in COUNT_PACKAGES:
        try:
            found[name] = version(name)
        except PackageNotFoundError:
            found[name] = None
    return found


# what a signal that ended the Valgrind process says about the count
_SIGNAL_MEANING = {
    "SIGILL": (f"the kernel uses instructions Valgrind cannot run (compiled for a CPU with instructions Valgrind "
               f"lacks, such as AVX-512; the counted kernels are compiled for {COUNT_TARGET}: a kernel or library "
               f"compiled for the host CPU instead reached the count)"),
    "SIGKILL": "killed from outside (the kernel's out-of-memory killer, or a user)",
    "SIGSEGV": "the process crashed (a bad memory access)",
    "SIGBUS": "the process crashed (a bad memory access)",
    "SIGABRT": "the process aborted",
    "SIGTERM": "stopped from outside",
}


def failure_text(returncode: int, last_line: str, process: str = "the Valgrind process") -> str:
    """Why ``process`` (a counting process) that ended with ``returncode`` gave no count, in
    one line: a negative code is the signal that killed it, named, with what it means here."""
    import signal

    if returncode < 0:
        try:
            name = signal.Signals(-returncode).name
        except ValueError:
            name = f"signal {-returncode}"
        meaning = _SIGNAL_MEANING.get(name) or signal.strsignal(-returncode) or "no description"
        said = f"; it said: {last_line}" if last_line else ""
        return f"{process} was killed by {name}: {meaning}{said}"
    return f"{process} exited with {returncode}: {last_line or 'no message on stderr'}"
