# SPDX-License-Identifier: MIT
"""Keeps ParaView's Python on ParaView's VTK modules (put on PYTHONPATH by the pvpython/pvbatch
wrappers that scripts/setup.sh writes into build-paraview/; docs/paraview.md).

ParaView's unpacked python3-paraview sits on PYTHONPATH, but pvpython, after start-up, puts the
folder where it finds a `vtkmodules` next to its libraries first on sys.path: with Debian's
python3-vtk9 installed that is Debian's VTK 9.1 Python package, whose modules crash against
ParaView's VTK libraries. This hook runs before `vtkmodules`, `vtk` or `paraview` is first
imported and drops from sys.path the folders with a `vtkmodules` that come before the one beside
the `paraview` package on PYTHONPATH (later ones, such as /usr/lib/python3/dist-packages with
NumPy, stay: ParaView's folder comes first)."""
import os
import sys


def _ours():
    for p in os.environ.get("PYTHONPATH", "").split(os.pathsep):
        if p and os.path.isfile(os.path.join(p, "paraview", "__init__.py")):
            return os.path.realpath(p)
    return None


class _KeepParaViewVTK:
    """A meta-path finder that finds nothing: it only cleans sys.path first."""

    def __init__(self, ours):
        self.ours = ours

    def find_spec(self, name, path=None, target=None):
        if path is None and name in ("vtkmodules", "vtk", "paraview"):
            real = [os.path.realpath(p or ".") for p in sys.path]
            if self.ours in real:
                first = real.index(self.ours)
                sys.path[:first] = [p for p in sys.path[:first]
                                    if not os.path.isdir(os.path.join(p or ".", "vtkmodules"))]
        return None


_dir = _ours()
if _dir is not None:
    sys.meta_path.insert(0, _KeepParaViewVTK(_dir))

# Debian's ParaView 5.11 (python3-paraview 5.11.0+dfsg-1) loads Python plugins through
# paraview.detail.pythonalgorithm, which imports inspect.getargspec: removed in Python 3.11,
# the Python it is built for, so every Python plugin fails to load. The old function, from
# getfullargspec (same fields, varkw named keywords), for ParaView's processes only.
import inspect  # noqa: E402

if not hasattr(inspect, "getargspec"):
    from collections import namedtuple

    _ArgSpec = namedtuple("ArgSpec", "args varargs keywords defaults")

    def _getargspec(func):
        s = inspect.getfullargspec(func)
        return _ArgSpec(s.args, s.varargs, s.varkw, s.defaults)

    inspect.getargspec = _getargspec
