"""Scalar operations the kernels call at many sites, lowered by Numba straight to LLVM.

A Numba function with ``inline="always"`` is inlined anew at every call site: Numba runs its
front end and deep-copies its IR each time, and the traversal and lane walks call these few
operations at over a hundred sites, most of them inside helpers that are inlined again. Here
each is a plain Python function with a typing rule and a lowering of its own, as Numba's
builtins are, so a call costs a few LLVM instructions to emit and nothing to inline. The
machine code is what the inlined versions gave (the traversal's, the lane walk's and the
batches', instruction for instruction; the GPU's PTX too), and with an empty cache a first
error-aware render of ``builtin:pillars`` compiled in 82-84 s instead of 88-91, a first
reference render in 48-50 s instead of 50-53 (Intel Xeon, two cores).

``lane_walk.pick`` is not one of them: lowered the same way, its lane pass came out with
other mask instructions and one-ray renders took about 1.05× the time; compiled once per type
through an overload, its code is unchanged.

The plain Python bodies are what runs where nothing is compiled: ``NUMBA_DISABLE_JIT``, as
in the CUDA simulator. numba-cuda compiles the same typing and lowering for the GPU.
"""

from __future__ import annotations

from numba import types
from numba.core.typing.templates import signature
from numba.extending import lower_builtin, type_callable

__all__ = ["face_time", "fmax", "fmin"]


def fmax(a: float, b: float) -> float:
    """max for non-NaN numbers without the builtin's NaN handling: a plain select, which loops
    over many rays vectorise."""
    return a if a > b else b


def fmin(a: float, b: float) -> float:
    return a if a < b else b


def face_time(plane: int, o: float, inv: float) -> float:
    """Crossing time of the integer plane ``plane`` on one axis: the contract's one formula."""
    return (float(plane) - o) * inv


def _common_number_type(context, *values):
    """The type both sides of a comparison are compared in, or None if they are not numbers."""
    plain = [types.unliteral(value) for value in values]
    if not all(isinstance(value, types.Number) for value in plain):
        return None
    return context.unify_types(*plain)


def _greater(builder, type_, a, b):
    """``a > b`` in ``type_``: ordered for floats, signed or unsigned for integers."""
    if isinstance(type_, types.Float):
        return builder.fcmp_ordered(">", a, b)
    return builder.icmp_signed(">", a, b) if type_.signed else builder.icmp_unsigned(">", a, b)


def _typed_pair(context, a, b):
    common = _common_number_type(context, a, b)
    if common is None:
        return None
    return signature(common, common, common)


@type_callable(fmax)
def _type_fmax(context):
    return lambda a, b: _typed_pair(context, a, b)


@type_callable(fmin)
def _type_fmin(context):
    return lambda a, b: _typed_pair(context, a, b)


@lower_builtin(fmax, types.Number, types.Number)
def _lower_fmax(context, builder, signature_, args):
    a, b = args
    return builder.select(_greater(builder, signature_.return_type, a, b), a, b)


@lower_builtin(fmin, types.Number, types.Number)
def _lower_fmin(context, builder, signature_, args):
    a, b = args
    return builder.select(_greater(builder, signature_.return_type, b, a), a, b)


@type_callable(face_time)
def _type_face_time(context):
    def typer(plane, o, inv):
        if _common_number_type(context, plane, o, inv) is None:
            return None
        return signature(types.float64, types.float64, types.float64, types.float64)

    return typer


@lower_builtin(face_time, types.float64, types.float64, types.float64)
def _lower_face_time(context, builder, signature_, args):
    plane, o, inv = args
    return builder.fmul(builder.fsub(plane, o), inv)
