"""Integers reinterpreted as pointers in numba kernels (no MuJoCo here: the batched loop uses them too).

A kernel that must write into arrays it cannot take as one argument (the N records' row windows
of a batch, each its own numpy array) takes their addresses (``array.ctypes.data``) and views each
one with ``numba.carray(f64_ptr(address), shape)``. The caller keeps the arrays alive and
C-contiguous while the kernel runs.
"""

from __future__ import annotations

from numba import types
from numba.extending import intrinsic


@intrinsic
def f64_ptr(typingctx, address):
    """Reinterpret an integer address as ``double*`` (numba intrinsic)."""
    sig = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

    return sig, codegen


@intrinsic
def i64_ptr(typingctx, address):
    """Reinterpret an integer address as ``int64*`` (numba intrinsic)."""
    sig = types.CPointer(types.int64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int64)))

    return sig, codegen
