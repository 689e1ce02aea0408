# SPDX-License-Identifier: MIT
"""Shared fixtures: where the built `wvol` program is, and a scratch directory."""
import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
WVOL_BIN = os.environ.get("WVOL_BIN", str(ROOT / "build" / "wvol"))


def run_wvol(*args, cwd=None, check=False):
    """Runs the wvol program; returns the CompletedProcess (text mode)."""
    proc = subprocess.run([WVOL_BIN, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          timeout=600)
    if check and proc.returncode != 0:
        raise AssertionError(f"wvol {' '.join(map(str, args))} failed ({proc.returncode}):\n"
                             f"{proc.stdout}\n{proc.stderr}")
    return proc


@pytest.fixture
def wvol():
    return run_wvol
