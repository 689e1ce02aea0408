# SPDX-License-Identifier: MIT
"""bench/bench_ab_bytes.py, the two-build comparison, on one build against itself at 32^3: every
case must come out identical (the same file bytes, the same decoded volume), so a script that
compared the wrong files or lost a case fails here."""
import json
import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
WVOL = os.environ.get("WVOL_BIN", str(ROOT / "build" / "wvol"))


def test_one_build_against_itself_is_identical(tmp_path):
    out = tmp_path / "ab"
    subprocess.run([sys.executable, str(ROOT / "bench" / "bench_ab_bytes.py"), "--base", WVOL, "--new", WVOL,
                    "--size", "32", "--rounds", "1", "--out", str(out)], check=True, stdout=subprocess.DEVNULL,
                   cwd=ROOT / "bench")
    res = json.loads(out.with_suffix(".json").read_text())
    rows = res["rows"]
    # three volumes, two option sets, three rates
    assert len(rows) == 18
    assert {(r["volume"], r["config"], r["psnr"]) for r in rows} == {
        (v, c, p) for v in ("skull", "shepp-logan", "turbulence") for c in ("default", "db2, 5 levels")
        for p in (40, 50, 60)}
    for r in rows:
        assert r["bytes_base"] == r["bytes_new"] > 0 and r["files_identical"], r
        assert r["bytes_ratio"] == 1.0
        assert r["decoded_identical"], r
        assert 0 < r["decompress_cpu_s_base"] < 60 and 0 < r["decompress_cpu_s_new"] < 60
    md = out.with_suffix(".md").read_text()
    assert sum(line.startswith("|") for line in md.splitlines()) == 2 + 18  # header, rule, a line per case
