# SPDX-License-Identifier: MIT
"""An X server for ParaView's renderings (Debian's ParaView renders through GLX: it needs one).

`display()` starts Xvfb with -displayfd, so the server itself picks a free display number and
says when it is ready: no race with other X servers on the machine, unlike xvfb-run -a's guess.
Used by tests/python/test_paraview.py and bench/bench_paraview.py."""
import contextlib
import os
import subprocess
import tempfile


@contextlib.contextmanager
def display(screen="800x600x24"):
    """Yields the DISPLAY string of a fresh Xvfb, stopped on exit."""
    r, w = os.pipe()
    # its messages go to a file: a pipe nobody reads would fill and stop the server
    with tempfile.TemporaryFile() as log:
        # -noreset: the server would otherwise reset when its last client leaves, and ParaView
        # opens and closes a probing connection before its window: the next one could fail
        p = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", screen, "-nolisten", "tcp", "-noreset"],
                             pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=log)
        os.close(w)
        with os.fdopen(r, "rb") as f:
            num = f.readline().strip()  # written once the server accepts connections
        try:
            if not num:
                p.wait(timeout=30)
                log.seek(0)
                raise RuntimeError(f"Xvfb did not start: {log.read().decode(errors='replace')}")
            yield f":{num.decode()}"
        finally:
            p.terminate()
            p.wait(timeout=30)
