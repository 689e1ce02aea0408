# SPDX-License-Identifier: MIT
"""wvol basis: the spline tables' checks per family and J, JSON and CSV output."""
import csv
import json


def test_basis_json_db2(wvol):
    r = wvol("basis", "--wavelet", "db2", "-J", "4:6", "--json")
    assert r.returncode == 0, r.stderr
    bases = json.loads(r.stdout)["bases"]
    assert [b["J"] for b in bases] == [4, 5, 6]
    for b in bases:
        assert b["pieces_per_unit"] == 2 ** b["J"] and b["pieces"] == 3 * 2 ** b["J"]
        assert abs(b["phi_integral"] - 1) < 1e-14 and abs(b["psi_integral"]) < 1e-14
        assert abs(b["center"] - 0.6339745962155614) < 1e-12
    # measured 0.40, 0.27, 0.19: the error falls as J grows
    errs = [b["spline_error"] for b in bases]
    assert errs[0] > errs[1] > errs[2] and errs[2] < 0.4


def test_basis_text_has_plot_line(wvol):
    r = wvol("basis", "--wavelet", "db2", "-J", "6")
    assert r.returncode == 0, r.stderr
    assert "db2 J=6: 64 pieces per unit, spline error" in r.stdout


def test_basis_all_families_haar_exact(wvol):
    r = wvol("basis", "-J", "3", "--json")
    assert r.returncode == 0, r.stderr
    bases = {b["wavelet"]: b for b in json.loads(r.stdout)["bases"]}
    assert len(bases) == 17
    assert bases["haar"]["exact"] == 1 and bases["haar"]["spline_error"] == 0.0
    assert bases["db10"]["spline_error"] < bases["db2"]["spline_error"]


def test_basis_csv(wvol, tmp_path):
    out = tmp_path / "db2.csv"
    r = wvol("basis", "--wavelet", "db2", "-J", "2", "--csv", out)
    assert r.returncode == 0, r.stderr
    rows = [row for row in csv.reader(l for l in out.read_text().splitlines() if not l.startswith("#"))]
    assert rows[0][:3] == ["piece", "x0", "phi_c0"] and len(rows) == 1 + 12
    assert all(len(row) == len(rows[0]) for row in rows)
    assert float(rows[1][2]) == 0.0  # phi(0) = 0
    assert float(rows[1][rows[0].index("phi_int_c0")]) == 0.0  # the primitive starts at 0


def test_basis_bad_usage(wvol):
    r = wvol("basis", "-J", "13")
    assert r.returncode == 2 and "-J" in r.stderr
    r = wvol("basis", "--wavelet", "db42")
    assert r.returncode == 2 and "db42" in r.stderr
    r = wvol("basis", "--csv", "x.csv")
    assert r.returncode == 2 and "--csv needs one --wavelet and one -J value" in r.stderr
