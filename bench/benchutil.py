# SPDX-License-Identifier: MIT
"""Helpers the benchmarks share (the scripts in bench/ import it from their own folder)."""
import platform


def cpu_model():
    """The CPU's model name, for the machine line of a results file."""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"
