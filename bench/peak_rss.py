# SPDX-License-Identifier: MIT
"""Runs a command and writes its peak resident memory (bytes, the kernel's accounting of the
child via wait4) to PREFIX.<rank> (the MPI rank from Open MPI's environment, else 0); exits
with the command's status. Under mpiexec each rank runs its own copy, so every rank's peak is
measured: python3 peak_rss.py PREFIX CMD [ARGS...]"""
import os
import subprocess
import sys

prefix, cmd = sys.argv[1], sys.argv[2:]
p = subprocess.Popen(cmd)
_, status, ru = os.wait4(p.pid, 0)
rank = os.environ.get("OMPI_COMM_WORLD_RANK", os.environ.get("PMI_RANK", "0"))
with open(f"{prefix}.{rank}", "w") as f:
    f.write(str(ru.ru_maxrss * 1024))
sys.exit(os.waitstatus_to_exitcode(status))
