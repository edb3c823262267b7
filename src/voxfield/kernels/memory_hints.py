"""``prefetch``: ask the memory system for an array element a kernel will read soon.

A walk that knows early which cell it will settle in can start that cell's other loads
before it needs them, so their cache misses overlap the one it waits for instead of
following it. The hint changes no result; where the element is cached already it costs an
instruction.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, overload

__all__ = ["prefetch"]


def prefetch(array, index) -> None:
    """Prefetch ``array[index]`` for reading into every cache level (LLVM's
    ``llvm.prefetch``) in compiled code; plain Python (``NUMBA_DISABLE_JIT``, the CUDA
    simulator) has nothing to do. ``index`` is an integer for a 1-D array, else a tuple of
    one integer per dimension. No bounds check: an index outside the array prefetches
    nothing useful and faults on nothing."""


@overload(prefetch, inline="always")
def _prefetch(array, index):
    if not isinstance(array, types.Array):
        return None
    if isinstance(index, types.Integer):
        if array.ndim != 1:
            return None
    elif not (isinstance(index, types.UniTuple) and index.count == array.ndim
              and isinstance(index.dtype, types.Integer)):
        return None

    def hint(array, index):
        _llvm_prefetch(array, index)

    return hint


@intrinsic
def _llvm_prefetch(typingctx, array, index):
    def codegen(context, builder, signature, args):
        array_type = signature.args[0]
        view = context.make_array(array_type)(context, builder, args[0])
        index_type = signature.args[1]
        indices = (cgutils.unpack_tuple(builder, args[1], index_type.count)
                   if isinstance(index_type, types.UniTuple) else [args[1]])
        pointer = cgutils.get_item_pointer(context, builder, array_type, view, indices,
                                           wraparound=False)
        byte_pointer = ir.IntType(8).as_pointer()
        int32 = ir.IntType(32)
        # ``declare_intrinsic`` names it for the pointer type: ``.p0`` with LLVM's opaque
        # pointers, ``.p0i8`` with typed ones (older Numba).
        hint = builder.module.declare_intrinsic(
            "llvm.prefetch", [byte_pointer],
            ir.FunctionType(ir.VoidType(), [byte_pointer, int32, int32, int32]))
        # read, keep in all cache levels, data cache
        builder.call(hint, [builder.bitcast(pointer, byte_pointer), int32(0), int32(3),
                            int32(1)])
        return context.get_dummy_value()

    return types.void(array, index), codegen
