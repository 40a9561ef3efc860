"""Host (numpy) arrays handed to Dr.Jit: :func:`jit_array`; device arrays assembled from
parts: :class:`Assembled`.

On the LLVM backend Dr.Jit does not copy a numpy array it is given: it maps the array's own
memory, and compiles each kernel that reads it for that memory's alignment (a vector load
``align 64`` where the address is a multiple of the vector's size, ``align 1`` elsewhere).
The alignment is part of the kernel's hash. numpy's allocations are 16-byte aligned, so
whether a buffer is 64-byte aligned changes from one call to the next, and so does the
hash: every new set of host arrays could compile the kernels that read them again (the
boundary terms' adjoint kernels did, at every gradient step). The mapped memory also stays
the numpy array's: writing to the array later would change the Dr.Jit value.

:func:`jit_array` hands Dr.Jit a private copy at an address aligned to ALIGN bytes (16
lanes of 8-byte values), so the kernels that read it are always the same kernels. On the
CUDA backend the array is copied to the device anyway; the copy here costs one host pass.
"""

import drjit as dr
import numpy as np

ALIGN = 128  # bytes: a vector of 16 lanes of the widest (8-byte) type


def jit_array(cls, values):
    """``values`` (array-like) as a Dr.Jit array of type ``cls`` (mi.Float, mi.UInt32,
    mi.Bool, ...), from an aligned private copy (see the module docstring)."""
    values = np.asarray(values, dtype=_DTYPES[dr.type_v(cls)])
    buffer = np.empty(values.nbytes + ALIGN, np.uint8)
    start = -buffer.ctypes.data % ALIGN
    out = buffer[start:start + values.nbytes].view(values.dtype)
    out[...] = values.ravel()
    return cls(out)


def jit_tensor(values):
    """A float32 numpy array (an image) as a ``mi.TensorXf`` of its shape, from an aligned
    private copy (see the module docstring)."""
    import mitsuba as mi

    values = np.asarray(values, np.float32)
    return mi.TensorXf(jit_array(mi.Float, values.ravel()), shape=values.shape)


class Assembled:
    """A Dr.Jit array of type ``cls`` and width ``total`` assembled on the device from parts
    that cover it (:meth:`add`), in :attr:`array`: a part that covers it all is the array
    itself; otherwise each is scattered at its offset, given as data (``dr.concat`` makes
    the offsets constants of one kernel, compiled anew for each count of parts), and
    launched at once, so that the parts are freed as they come."""

    def __init__(self, cls, total):
        self.cls, self.total = cls, total
        self.array = None  # (None: no part yet)

    def add(self, first, part):
        """The entries first .. first + width(part) - 1 of the array are ``part``'s."""
        if self.array is None and first == 0 and dr.width(part) == self.total:
            self.array = part
            return
        if self.array is None:
            self.array = dr.empty(self.cls, self.total)
        index = dr.uint32_array_t(self.cls)
        dr.scatter(self.array, part, dr.arange(index, dr.width(part)) + dr.opaque(index, first))
        dr.eval(self.array)


_DTYPES = {dr.VarType.Float32: np.float32, dr.VarType.Float64: np.float64,
           dr.VarType.UInt32: np.uint32, dr.VarType.Int32: np.int32,
           dr.VarType.UInt64: np.uint64, dr.VarType.Int64: np.int64, dr.VarType.Bool: np.bool_}
