"""Software prefetch for numba kernels: ask for an array element's cache line without waiting.

A plain load of memory that misses every cache (a table row of a particle far from the previous
one) must complete before the instructions behind it retire; when the wait is longer than the
reorder buffer lasts, the core stalls. A prefetch instruction retires at once and only starts
the transfer, so the work of the current particle goes on while the next one's row arrives.
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

__all__ = ["prefetch"]

_I8P = ir.IntType(8).as_pointer()
_I32 = ir.IntType(32)
_FN = ir.FunctionType(ir.VoidType(), [_I8P, _I32, _I32, _I32])


@intrinsic
def prefetch(typingctx, array, i):
    """Prefetch (for reading, into every cache level) the line holding element ``i`` of the
    C-contiguous ``array``'s data, counted flat (row-major). For numba kernels only (LLVM's
    ``llvm.prefetch``: an x86 ``prefetcht0``); it never faults, so any ``i`` is safe, but one
    outside the array fetches someone else's line for nothing.
    """
    if not (isinstance(array, types.Array) and array.layout == "C"):
        return None
    if not isinstance(i, types.Integer):
        return None
    sig = types.void(array, types.intp)

    def codegen(context, builder, signature, args):
        arr, index = args
        data = context.make_array(signature.args[0])(context, builder, arr).data
        ptr = builder.bitcast(builder.gep(data, [index]), _I8P)
        # p0i8: the name LLVM 14 wants; newer LLVMs (opaque pointers) accept it as llvm.prefetch.p0
        fn = cgutils.get_or_insert_function(builder.module, _FN, "llvm.prefetch.p0i8")
        # rw = 0 (read), locality = 3 (keep in every level), cache type = 1 (data)
        builder.call(fn, [ptr, _I32(0), _I32(3), _I32(1)])
        return context.get_dummy_value()

    return sig, codegen
