"""Arrays handed to the package's cached compiled helpers (not kernels: the CSV formatter,
the metrics' reversal loop). Kept out of ``blocks.kernel``, whose source is hashed into every
plan's name: a helper here changes no kernel's cache key."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt


def compiled_arg(a: npt.ArrayLike, dtype: Any = np.float64) -> Any:
    """``a`` as an argument of a cached compiled function: C-contiguous, of ``dtype`` and
    writable. numba types a read-only array (a pyarrow column's, a frozen record's) apart
    from a writable one, so without this one function compiles twice, once per kind of
    array (8 s each for the CSV formatter); a read-only array is copied."""
    out = np.ascontiguousarray(a, dtype=dtype)
    return out if out.flags.writeable else out.copy()
