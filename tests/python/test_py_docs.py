# SPDX-License-Identifier: MIT
"""The README / docs/python.md example runs as written (so the docs cannot rot)."""
import pathlib
import re

import numpy as np

from mesh_util import euler_if_watertight

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _example():
    text = (ROOT / "docs" / "python.md").read_text(encoding="utf-8")
    m = re.search(r"<!-- readme-example[^>]*-->\s*```python\n(.*?)```", text, re.S)
    assert m, "docs/python.md lost its marked example"
    return m.group(1)


def test_readme_shows_the_same_example():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert f"```python\n{_example()}```" in readme


def test_readme_example_is_five_lines_and_runs(tmp_path, monkeypatch, capsys):
    code = _example()
    assert len(code.strip().splitlines()) == 5
    monkeypatch.chdir(tmp_path)
    ns = {}
    exec(compile(code, "docs/python.md", "exec"), ns)
    kept, predicted, measured = capsys.readouterr().out.split()
    assert int(kept) == ns["store"].kept == round(0.05 * 64 ** 3)
    # 64^3 needs no padding: the Parseval prediction is the measured PSNR (float32 rounding)
    assert abs(float(predicted) - float(measured)) < 0.01
    verts, faces, normals = ns["verts"], ns["faces"], ns["normals"]
    assert verts.dtype == normals.dtype == np.float32 and faces.dtype == np.uint32
    # one closed surface: the f = 0.5 sphere of the Gaussian, radius 0.294 * E / 2 with
    # E = 64 (docs/datasets.md); 2% covers the linear interpolation of marching cubes
    assert euler_if_watertight(verts, faces) == 2 and len(faces) > 1000
    r = np.linalg.norm(verts.astype(np.float64), axis=1)
    assert abs(r.mean() - 0.294 * 32) < 0.02 * 0.294 * 32
