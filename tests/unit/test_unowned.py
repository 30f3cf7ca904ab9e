"""``kernels.unowned``: views without a memory record for the compiled solver loops.

The solver loops take such views of their arrays at entry so that numba counts no references
in the loop (docs/performance.md: 59 % of the default solve's compiled time on one machine).
The views must be the same memory as their owners (the loops write their results through
them), and must really carry no memory record: numba boxes an array it allocated with its
memory record as ``base``, and a view without one with no ``base`` and no data of its own.
A numba or cffi upgrade that changed either would fail here, loudly, instead of silently
slowing the solvers down or writing into copies.
"""

import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

from roughvib.model import kernels as kn


@njit
def _write_through(a, b, c, e):
    ua, ub, uc, ue = kn.unowned(a), kn.unowned(b), kn.unowned(c), kn.unowned(e)
    ua[1] = 5.0
    ub[1, 2] = 7
    uc[0, 1, 1] = -1.5
    total = 0.0
    for i in range(ua.size):
        total += ua[i]
    return ua.shape[0], ub.shape[0], ub.shape[1], uc.shape[2], ue.shape[0], total, ub[0, 1]


@njit
def _view_of(a):
    return kn.unowned(a)


@njit
def _allocated(n):
    return np.empty(n)


def test_views_are_the_owners_memory():
    a = np.arange(4.0)
    b = np.arange(6, dtype=np.int64).reshape(2, 3)
    c = np.zeros((2, 2, 2))
    e = np.zeros(0)
    n_a, b0, b1, c2, n_e, total, b01 = _write_through(a, b, c, e)
    assert (n_a, b0, b1, c2, n_e) == (4, 2, 3, 2, 0)
    assert a.tolist() == [0.0, 5.0, 2.0, 3.0]       # written through the view
    assert b[1, 2] == 7 and b01 == 1                 # C order, int64 kept
    assert c[0, 1, 1] == -1.5
    assert total == 10.0                             # read through the view: 0 + 5 + 2 + 3


def test_view_has_no_memory_record():
    a = np.arange(3.0)
    v = _view_of(a)
    assert np.shares_memory(v, a)
    assert v.base is None and not v.flags.owndata    # boxed without a memory record
    # the contrast: what numba allocates is boxed with its memory record as base
    assert _allocated(3).base is not None


def test_non_c_contiguous_array_is_refused():
    """The view is laid out in C order: a Fortran-ordered array would be read transposed."""
    f = np.asfortranarray(np.zeros((2, 3)))
    with pytest.raises(TypingError, match="C-contiguous"):
        _view_of(f)


def test_from_python_it_is_the_array_itself():
    """Plain Python (and ``NUMBA_DISABLE_JIT=1``) counts no references: nothing to take."""
    a = np.arange(3.0)
    assert kn.unowned(a) is a
