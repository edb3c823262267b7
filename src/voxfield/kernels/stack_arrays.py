"""``stack_matrix``: a small C-ordered 2-D array in the compiled caller's stack frame.

LLVM vectorises a loop over arrays only where it can tell that the loop's stores do not
change what its loads read. A kernel's arrays all arrive through arguments, which may
overlap as far as the compiler knows, and a load at a computed index (a gather from the
column pyramid) has no range to check at run time, so such a loop stays scalar. Memory on
the stack is the caller's own: nothing else can point into it, and a loop that keeps its
state there and gathers from the arguments vectorises (``kernels.lane_walk``).
"""

from __future__ import annotations

import numpy as np
from numba import config, types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import populate_array

__all__ = ["stack_matrix"]


@intrinsic
def _alloca_matrix(typingctx, rows, columns, dtype):
    if not (isinstance(rows, types.IntegerLiteral) and isinstance(columns, types.IntegerLiteral)
            and isinstance(dtype, (types.NumberClass, types.DType))):
        return None
    element = dtype.dtype
    array_type = types.Array(element, 2, "C")
    n_rows, n_columns = rows.literal_value, columns.literal_value

    def codegen(context, builder, signature, args):
        value_type = context.get_value_type(element)
        data = cgutils.alloca_once(builder, value_type, size=n_rows * n_columns)
        itemsize = context.get_abi_sizeof(value_type)
        intp = context.get_value_type(types.intp)
        array = context.make_array(array_type)(context, builder)
        populate_array(array, data=data, shape=[intp(n_rows), intp(n_columns)],
                       strides=[intp(n_columns * itemsize), intp(itemsize)],
                       itemsize=intp(itemsize), meminfo=None)
        return array._getvalue()

    return array_type(rows, columns, dtype), codegen


def _numpy_matrix(rows, columns, dtype):
    return np.empty((rows, columns), dtype)


#: ``stack_matrix(rows, columns, dtype)``: a ``rows × columns`` array of ``dtype``,
#: uninitialised, valid until the compiled function that asks for it returns; ``rows`` and
#: ``columns`` must be constants there. An intrinsic, so the allocation is always in the
#: caller's frame; in plain Python (``NUMBA_DISABLE_JIT``) a NumPy array.
stack_matrix = _numpy_matrix if config.DISABLE_JIT else _alloca_matrix
