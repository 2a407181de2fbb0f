"""CasADi's generated C called from compiled Python (numba) without the interpreter in
between: the per-tick kernels (interaction/observer/_tick_kernel.py) call the same shared library
:func:`~sixplus3.dynamics.codegen.compiled_small` built, through ctypes, on the
arrays of a :class:`~sixplus3.dynamics.compiled_kinematics.Buffered` (the same
buffers, the same numbers: tests/test_leadthrough.py).

A generated function has the C signature ``int f(const double** arg, double** res,
long long* iw, double* w, int mem)`` and ``f_work`` gives the sizes of its work arrays
(CasADi's code generation, with ``casadi_int`` = ``long long`` and ``casadi_real`` =
``double``, its defaults).  :class:`Native` keeps the pointer tables (the addresses of the
buffers' arrays, fixed while it lives) and the work arrays, and the library loaded."""

from __future__ import annotations

import ctypes
from typing import Any

import numpy as np

from sixplus3.dynamics import library_index
from sixplus3.dynamics.codegen import cache_dir, codegen_enabled
from sixplus3.dynamics.compiled_kinematics import Buffered


class Native:
    """The generated function ``name`` (compiled for ``key``) on the arrays of ``buf``:
    :attr:`ptrs` = [the function, arg table, res table, iw, w] (addresses, uint64), so
    that a kernel's ``call_casadi(*ptrs)`` (dynamics/_ccall.py) evaluates it on
    ``buf.args`` into ``buf.res``."""

    def __init__(self, name: str, key: str, buf: Buffered) -> None:
        lib = library_index.lookup(name, key, cache_dir()) if codegen_enabled() else None
        if lib is None:
            raise OSError(f"{name}: no compiled library for this robot")
        self._lib = ctypes.CDLL(str(lib))
        fn: Any = getattr(self._lib, name)
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_int]
        work: Any = getattr(self._lib, f"{name}_work")
        work.restype = ctypes.c_int
        work.argtypes = [ctypes.POINTER(ctypes.c_longlong)] * 4
        sz = [ctypes.c_longlong() for _ in range(4)]
        if work(*[ctypes.byref(s) for s in sz]) != 0:
            raise OSError(f"{name}: its work sizes are not available")
        n_arg, n_res, n_iw, n_w = (int(s.value) for s in sz)
        if n_arg < len(buf.args) or n_res < len(buf.res):
            raise OSError(f"{name}: {n_arg} arguments and {n_res} results, the buffer "
                          f"has {len(buf.args)} and {len(buf.res)}")
        self.buf = buf
        self._arg = np.zeros(max(n_arg, 1), dtype=np.uint64)
        self._res = np.zeros(max(n_res, 1), dtype=np.uint64)
        for i, a in enumerate(buf.args):
            self._arg[i] = a.ctypes.data
        for j, r in enumerate(buf.res):
            self._res[j] = r.ctypes.data
        self._iw = np.zeros(max(n_iw, 1), dtype=np.int64)
        self._w = np.zeros(max(n_w, 1))
        self.fn = fn
        addr = ctypes.cast(fn, ctypes.c_void_p).value
        self.ptrs = np.array([addr, self._arg.ctypes.data, self._res.ctypes.data,
                              self._iw.ctypes.data, self._w.ctypes.data], dtype=np.uint64)


def native(name: str, key: str, buf: Buffered) -> Native | None:
    """:class:`Native` of ``name`` on ``buf``, or None where there is no compiled
    library (code generation off, a read-only cache: the caller keeps CasADi's buffer
    interface, the same numbers)."""
    try:
        return Native(name, key, buf)
    except (OSError, AttributeError):
        return None


__all__ = ["Native", "native"]
