# SPDX-License-Identifier: MIT
"""The wvol program's contract: exit codes 0/1/2 and one clear line on stderr."""
import json

import numpy as np
import pytest

from conftest import run_wvol


def test_no_command_is_usage_error(wvol):
    r = wvol()
    assert r.returncode == 2
    assert "usage" in r.stderr


def test_unknown_command(wvol):
    r = wvol("frobnicate")
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == ["wvol: unknown command 'frobnicate' (run 'wvol --help' for the list)"]


def test_help_lists_commands(wvol):
    r = wvol("--help")
    assert r.returncode == 0
    assert "info" in r.stdout


def test_info_unknown_option(wvol):
    r = wvol("info", "--bogus", "x.raw")
    assert r.returncode == 2
    assert "--bogus" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_info_missing_file(wvol, tmp_path):
    r = wvol("info", tmp_path / "nope.raw", "--dims", "4x4x4")
    assert r.returncode == 1
    assert "nope.raw" in r.stderr


def test_info_raw_size_mismatch(wvol, tmp_path):
    p = tmp_path / "v.raw"
    p.write_bytes(b"\0" * (4 * 4 * 4 * 4 - 1))
    r = wvol("info", p, "--dims", "4x4x4")
    assert r.returncode == 1
    assert "file has 255 bytes but 4x4x4 float32 samples need 256" in r.stderr


def test_info_overflowing_dims(wvol, tmp_path):
    p = tmp_path / "v.raw"
    p.write_bytes(b"\0" * 16)
    r = wvol("info", p, "--dims", "4294967296x4294967296x4294967296")
    assert r.returncode == 2  # impossible dimensions are bad usage
    assert "dimensions 4294967296x4294967296x4294967296 overflow" in r.stderr


def test_info_malformed_dims(wvol, tmp_path):
    p = tmp_path / "v.raw"
    p.write_bytes(b"\0" * 16)
    for bad in ("4x4", "ax4x4", "0x4x4", "4x4x4x4", "-4"):
        r = wvol("info", p, "--dims", bad)
        assert r.returncode == 2, bad
        assert "--dims" in r.stderr, bad


def test_info_raw_json(wvol, tmp_path):
    import numpy as np
    a = np.arange(2 * 3 * 4, dtype="<f4").reshape(4, 3, 2)  # (z, y, x)
    p = tmp_path / "v.raw"
    a.tofile(p)
    r = wvol("info", p, "--dims", "2x3x4", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["dims"] == [2, 3, 4]
    assert d["min"] == 0 and d["max"] == 23
    assert abs(d["mean"] - 11.5) < 1e-12


def test_info_percentiles_of_a_constant_volume_are_its_value(tmp_path):
    # the 1024-bin histogram of a constant volume has width 0: its percentiles are the value
    # itself, not the value + 1 (a bin width of 1 stood in for 0)
    raw = tmp_path / "c.raw"
    np.full((4, 4, 4), 0.00248, np.float32).tofile(raw)
    r = run_wvol("info", raw, "--dims", "4x4x4", "--json")
    assert r.returncode == 0, r.stderr
    pct = json.loads(r.stdout)["percentiles"]
    assert pct and all(v == pytest.approx(0.00248, rel=1e-6) for v in pct.values()), pct
