"""Calling CasADi's generated C from numba kernels by address (dynamics/native.py).

numba can call a ctypes function object, but it unboxes one on every call from Python
through ``ctypes.cast`` (about 2 us a function); :func:`call_casadi` takes the
function's address as an integer instead, so a kernel's arguments are plain arrays and
numba's on-disk cache stays valid (no address is compiled in)."""

from __future__ import annotations

from typing import Any

from llvmlite import ir
from numba import types
from numba.extending import intrinsic


def _call_casadi(typingctx, fn, arg, res, iw, w):  # type: ignore[no-untyped-def]
    """``fn(arg, res, iw, w, 0)`` for a generated function at the address ``fn``
    (``int f(const double**, double**, long long*, double*, int)``); every argument an
    address (an integer)."""
    for t in (fn, arg, res, iw, w):
        if not isinstance(t, types.Integer):
            return None
    sig = types.int32(fn, arg, res, iw, w)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        i8p = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.IntType(32), [i8p, i8p, i8p, i8p, ir.IntType(32)])
        f, a, r, i, v = args
        ptr = builder.inttoptr(f, fnty.as_pointer())
        return builder.call(ptr, [builder.inttoptr(a, i8p), builder.inttoptr(r, i8p),
                                  builder.inttoptr(i, i8p), builder.inttoptr(v, i8p),
                                  ir.Constant(ir.IntType(32), 0)])

    return sig, codegen


#: (an intrinsic: numba compiles the call into the kernel that makes it)
call_casadi: Any = intrinsic(_call_casadi)

__all__ = ["call_casadi"]
