"""Borrowed views: arrays the compiled loop uses without numba's reference counting.

numba counts references to every array it handles. Each time compiled code binds an array to a
new name (an argument of a function that calls another one with it, an inlined helper's
parameter, a tuple unpacked, a slice) it adds one to the array's count with an atomic
instruction and takes it off again when the name dies. An atomic is a full memory barrier: the
processor waits for every earlier load and store before it goes on. In the RK4 sub-step those
barriers were most of the time: 70 % of the samples of ``perf record`` on speed-step landed on
the two instructions of NRT_incref and NRT_decref.

:func:`borrowed` gives a view of an array's data that carries no reference count (the view of
a C buffer that numba's ``carray`` makes: its memory record is null, and numba's incref and
decref then return at once). The loop rebinds every array it is given to such a view on entry;
everything it calls, controllers included, then runs without atomics.

:func:`borrowed_record` does the same for every array of a record (emasim.sim.core: a
NamedTuple of arrays, scalars and records), whatever its fields: the loop borrows its two
records in one call each.

Only arrays that outlive the loop may be borrowed: the arguments of ``run_ticks``, which the
caller (Python) holds for the whole call. Never borrow an array made inside compiled code; numba
would free it after its last use under its own name, and the view would dangle.
"""

import numba as nb
from numba import types
from numba.core import cgutils
from numba.core.extending import intrinsic

from ..jit import njit


@intrinsic
def _data_pointer(typingctx, array):
    """The pointer to an array's first element, typed with its dtype."""
    signature = types.CPointer(array.dtype)(array)

    def codegen(context, builder, sig, args):
        return context.make_array(sig.args[0])(context, builder, args[0]).data

    return signature, codegen


@njit(cache=True, inline="always", error_model="numpy")
def borrowed(array):
    """A view of a C-contiguous array's data without reference counting (module docstring)."""
    return nb.carray(_data_pointer(array), array.shape)


def _borrow_value(context, builder, typ, value):
    """``value`` of numba type ``typ`` with every array in it (a tuple's, recursively) made
    a view without a memory record (the LLVM of :func:`borrowed`)."""
    if isinstance(typ, types.Array):
        array = context.make_array(typ)(context, builder, value=value)
        array.meminfo = cgutils.get_null_value(array.meminfo.type)
        array.parent = cgutils.get_null_value(array.parent.type)
        return array._getvalue()
    if isinstance(typ, types.BaseTuple):
        for i, member in enumerate(typ.types):
            item = _borrow_value(context, builder, member, builder.extract_value(value, i))
            value = builder.insert_value(value, item, i)
    return value


@intrinsic
def borrowed_record(typingctx, record):
    """``record`` with each of its arrays borrowed (module docstring)."""
    signature = record(record)

    def codegen(context, builder, sig, args):
        return _borrow_value(context, builder, sig.args[0], args[0])

    return signature, codegen
