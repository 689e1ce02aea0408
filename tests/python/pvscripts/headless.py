# SPDX-License-Identifier: MIT
"""An X server for ParaView's renderings (Debian's ParaView renders through GLX: it needs one).

`display()` starts Xvfb with -displayfd, so the server itself picks a free display number and
says when it is ready: no race with other X servers on the machine, unlike xvfb-run -a's guess.
Used by tests/python/test_paraview.py and bench/bench_paraview.py."""
import contextlib
import os
import subprocess


@contextlib.contextmanager
def display(screen="800x600x24"):
    """Yields the DISPLAY string of a fresh Xvfb, stopped on exit."""
    r, w = os.pipe()
    p = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", screen, "-nolisten", "tcp"],
                         pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    os.close(w)
    with os.fdopen(r, "rb") as f:
        num = f.readline().strip()  # written once the server accepts connections
    try:
        if not num:
            raise RuntimeError(f"Xvfb did not start: {p.communicate(timeout=10)[1].decode(errors='replace')}")
        yield f":{num.decode()}"
    finally:
        p.terminate()
        p.wait(timeout=30)
