"""Loops compiled with numba on first use (the optional ``fast`` extra).

numba is imported when a loop first runs, not with the module that holds it
(the import alone takes about 0.4 s), and the machine code is cached on
disk (numba's ``cache=True``), so only the first process on a machine pays
for compiling. Without numba every caller has a numpy or pure-Python
version of its loop with the same results.
"""

import importlib.util


def numba_installed():
    """Whether numba can be imported, without importing it (that takes 0.4 s)."""
    try:
        return importlib.util.find_spec('numba') is not None
    except ValueError:  # a module set to None in sys.modules
        return False


class LazyLoop:
    """A plain-Python loop and its numba-compiled version, compiled on first use.

    Parameters
    ----------
    function : callable
        Written in the subset of Python that numba compiles, calling no
        other Python function.

    Attributes
    ----------
    available : bool
        Whether the compiled version can be used: numba is installed and,
        once :meth:`load` has run, could be imported.
    """

    def __init__(self, function):
        self._function = function
        self._compiled = None
        self.available = numba_installed()

    def load(self):
        """The compiled function; None when numba cannot be imported (``available`` turns False)."""
        if self._compiled is None and self.available:
            try:
                import numba
            except ImportError:  # installed but broken (e.g. a mismatched llvmlite)
                self.available = False
                return None
            self._compiled = numba.njit(cache=True, nogil=True)(self._function)
        return self._compiled
