"""The README / docs/python.md example runs as written (so the docs cannot rot)."""
import pathlib
import re

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _example():
    text = (ROOT / "docs" / "python.md").read_text(encoding="utf-8")
    m = re.search(r"<!-- readme-example[^>]*-->\s*```python\n(.*?)```", text, re.S)
    assert m, "docs/python.md lost its marked example"
    return m.group(1)


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
    coarse = ns["coarse"]
    assert coarse.data.shape == (32, 32, 32) and coarse.spacing == (2.0, 2.0, 2.0)
    assert np.isfinite(coarse.data).all() and abs(coarse.data.max() - 1.0) < 0.1    # the Gaussian's peak 1
