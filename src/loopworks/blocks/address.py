"""Arrays at an address, for generated plans (:mod:`loopworks.blocks.plan`).

A block's one-scan ``step`` from Python is called with the addresses of the block's two
buffers (``Block._bind`` takes them from the arrays it owns, and takes them again when the
buffers move, ``Block.adopt``), not the arrays themselves: numba then skips unboxing two
NumPy arrays and the reference counting of every slice it hands to the kernel, which is a
fifth of a single step's time. The block keeps the arrays alive while it holds their
addresses. Imported only by generated code (it imports numba).
"""

from __future__ import annotations

from typing import Any

from numba import types
from numba.extending import intrinsic

CPointer: Any = types.CPointer  # (numba's types are untyped)


def _codegen(dtype: Any) -> Any:
    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.inttoptr(args[0], context.get_value_type(CPointer(dtype)))
    return codegen


@intrinsic
def float64_at(typingctx: Any, address: Any) -> Any:
    """``float64_at(address)``: a float64 pointer, for ``numba.carray(float64_at(a), n)``."""
    return CPointer(types.float64)(types.int64), _codegen(types.float64)


@intrinsic
def int64_at(typingctx: Any, address: Any) -> Any:
    """``int64_at(address)``: an int64 pointer, for ``numba.carray(int64_at(a), n)``."""
    return CPointer(types.int64)(types.int64), _codegen(types.int64)
