# SPDX-License-Identifier: MIT
"""Per-pixel error bounds (wvol.render(..., bound=True), wvol render --bound): on every pixel the
image of the kept coefficients is within the bound of the image of all of them (both from the
exact X-ray paths), the CLI writes the same bound as Python, and bad requests are refused."""
import json

import numpy as np
import pytest

import wvol
from conftest import run_wvol
from test_render import read_exr_rgba

SIZE = (24, 20)


@pytest.fixture(scope="module")
def blobs():
    return wvol.synth.blobs(shape=(16, 16, 16), seed=3)


@pytest.mark.parametrize("camera", ["+z", "-x", "ortho dir=1,0.6,0.3"])
def test_bound_holds_on_every_pixel(blobs, camera):
    full = wvol.compress(blobs)
    kept = wvol.compress(blobs, keep=0.1, residual=True)
    # both by the exact paths (axis along an axis, else spline): the bound compares the models
    method = "auto" if camera in ("+z", "-x") else "spline"
    ia = wvol.render(full, camera, SIZE, mode="xray", method=method)
    ik, bd, st = wvol.render(kept, camera, SIZE, mode="xray", method=method, bound=True, return_stats=True)
    diff = np.abs(ia[..., :3].astype(np.float64) - ik[..., :3])
    # float32 images: half an ulp of each pixel allowed
    allow = (np.abs(ia[..., :3]) + np.abs(ik[..., :3])) * 2.0 ** -24
    assert np.all(diff <= bd[..., :3] + allow)
    assert np.all(np.isfinite(bd)) and np.all(bd >= 0)
    assert st["bound_max"] == pytest.approx(float(bd[..., :3].max()), rel=1e-6)
    assert diff.max() > 0.05 * st["bound_max"]  # the images do differ: the check is not vacuous


def test_cli_bound_matches_python(tmp_path, blobs):
    src = tmp_path / "blobs.nrrd"
    wvol.save(blobs, src)
    r = run_wvol("render", src, "-o", tmp_path / "x.exr", "--keep", "10%", "--mode", "xray", "--size",
                 f"{SIZE[0]}x{SIZE[1]}", "--bound", tmp_path / "b.exr", "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    b = read_exr_rgba(tmp_path / "b.exr").reshape(SIZE[1], 4, SIZE[0])   # per row: A, B, G, R
    # the CLI's render store is db2 (wvol.compress's default "auto" may choose another filter)
    _, bd = wvol.render(wvol.compress(blobs, "db2", keep=0.1, residual=True), "+z", SIZE, mode="xray", bound=True)
    assert np.array_equal(b[:, 3, :], bd[..., 0])
    assert info["bound_max"] == pytest.approx(float(bd[..., 0].max()), rel=1e-6)


def test_bound_refusals(tmp_path, blobs):
    with pytest.raises(ValueError, match="residual=True"):
        wvol.render(wvol.compress(blobs, keep=0.1), "+z", SIZE, mode="xray", bound=True)
    src = tmp_path / "blobs.nrrd"
    wvol.save(blobs, src)
    for extra, msg in ((["--bound", tmp_path / "b.png"], ".exr"),
                       (["--bound", tmp_path / "b.exr", "--mode", "absorption-linear"], "absorption-linear"),
                       (["--bound", tmp_path / "b.exr", "--shading"], "shading")):
        r = run_wvol("render", src, "-o", tmp_path / "x.exr", "--keep", "10%", *extra)
        assert r.returncode == 2 and msg in r.stderr, r.stderr
        assert not (tmp_path / "b.exr").exists()


def test_progressive_passes(blobs):
    full = wvol.render(wvol.compress(blobs, "db2"), "+z", SIZE, mode="xray")  # the passes' filter
    passes = list(wvol.render_progressive(blobs, "+z", SIZE, mode="xray"))
    assert passes[-1][2]["last"] and passes[-1][2]["stop"] == "complete"
    assert not any(info["last"] for _, _, info in passes[:-1])
    kept = [info["kept"] for _, _, info in passes]
    assert kept[0] == (16 >> 3) ** 3 and kept == sorted(kept)   # the low-pass cube (3 levels) first
    prev = None
    for img, bd, info in passes:
        diff = np.abs(full[..., :3].astype(np.float64) - img[..., :3])
        allow = (np.abs(full[..., :3]) + np.abs(img[..., :3])) * 2.0 ** -24
        assert np.all(diff <= bd[..., :3] + allow), info
        if prev is not None:   # the residual only shrinks: so does every pixel's bound
            assert np.all(bd <= prev)
        prev = bd
    assert passes[-1][2]["bound_max"] == 0


def test_progressive_stops_at_the_target(blobs):
    passes = list(wvol.render_progressive(blobs, "+z", SIZE, mode="xray"))
    target = passes[1][2]["bound_max"] * 1.001
    got = list(wvol.render_progressive(blobs, "+z", SIZE, mode="xray", max_error=target))
    assert len(got) == 2 and got[-1][2]["stop"] == "max-error"
    with pytest.raises(ValueError, match="growth"):
        next(wvol.render_progressive(blobs, growth=1.0))


def test_cli_progressive(tmp_path, blobs):
    src = tmp_path / "blobs.nrrd"
    wvol.save(blobs, src)
    r = run_wvol("render", src, "-o", tmp_path / "p.exr", "--mode", "xray", "--size", f"{SIZE[0]}x{SIZE[1]}",
                 "--progressive", "--bound", tmp_path / "b.exr", "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    n = len(info["passes"])
    assert info["stop"] == "complete" and n >= 2
    for k in range(n):
        assert (tmp_path / f"p.pass{k}.exr").exists() and (tmp_path / f"b.pass{k}.exr").exists()
    last = read_exr_rgba(tmp_path / "p.exr")
    assert np.array_equal(last, read_exr_rgba(tmp_path / f"p.pass{n - 1}.exr"))
    r = run_wvol("render", src, "-o", tmp_path / "q.exr", "--max-error", "1")
    assert r.returncode == 2 and "add --progressive" in r.stderr


def test_cli_progressive_max_error_without_a_bound_file(tmp_path, blobs):
    """--max-error alone computes the bound for its stop rule and writes no bound file (it used
    to crash on the bound file's missing name)."""
    src = tmp_path / "blobs.nrrd"
    wvol.save(blobs, src)
    r = run_wvol("render", src, "-o", tmp_path / "p.png", "--mode", "xray", "--size", f"{SIZE[0]}x{SIZE[1]}",
                 "--progressive", "--max-error", "0.5", "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    n = len(info["passes"])
    assert info["stop"] in ("max-error", "complete") and info["passes"][-1]["bound_max"] <= 0.5
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted(["blobs.nrrd", "p.png"] + [f"p.pass{k}.png" for k in range(n)]), names


def test_cli_progressive_failure_leaves_the_folder_as_found(tmp_path, blobs):
    """A pass that cannot be written (its bound's name is taken by a folder): the passes written
    before it are removed, and the folder holds what it held."""
    src = tmp_path / "blobs.nrrd"
    wvol.save(blobs, src)
    (tmp_path / "b.pass1.exr").mkdir()
    r = run_wvol("render", src, "-o", tmp_path / "p.exr", "--mode", "xray", "--size", f"{SIZE[0]}x{SIZE[1]}",
                 "--progressive", "--bound", tmp_path / "b.exr")
    assert r.returncode == 1 and "b.pass1.exr" in r.stderr, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.pass1.exr", "blobs.nrrd"]


def test_cli_bound_of_a_file_with_dropped_coefficients_is_bad_input(tmp_path, blobs):
    """The file's content rules the bound out (its dropped coefficients are not in it): exit 1,
    bad input (docs/cli.md), naming the remedy; no image is written."""
    src, kept = tmp_path / "blobs.nrrd", tmp_path / "kept.wvc"
    wvol.save(blobs, src)
    assert run_wvol("compress", src, "-o", kept, "--keep", "5%").returncode == 0
    r = run_wvol("render", kept, "-o", tmp_path / "k.exr", "--mode", "xray", "--size", "8x8", "--bound",
                 tmp_path / "kb.exr")
    assert r.returncode == 1 and "dropped coefficients before coding" in r.stderr, r.stderr
    assert not (tmp_path / "k.exr").exists() and not (tmp_path / "kb.exr").exists()


def test_coarse_bound_above_the_exact(tmp_path, blobs):
    kept = wvol.compress(blobs, "db2", keep=0.1, residual=True)  # the CLI's render store below is db2
    cam = "persp dir=1,0.6,0.3"
    _, exact = wvol.render(kept, cam, SIZE, mode="xray", bound="exact")
    _, coarse = wvol.render(kept, cam, SIZE, mode="xray", bound="coarse")
    assert np.all(coarse[..., :3] >= exact[..., :3] * (1 - 1e-5))
    with pytest.raises(ValueError, match="coarse"):
        wvol.render(kept, cam, SIZE, mode="xray", bound="tight")
    src = tmp_path / "blobs.nrrd"
    wvol.save(blobs, src)
    r = run_wvol("render", src, "-o", tmp_path / "x.exr", "--keep", "10%", "--mode", "xray", "--camera", cam,
                 "--size", f"{SIZE[0]}x{SIZE[1]}", "--bound", tmp_path / "b.exr", "--bound-method", "coarse", "--json")
    assert r.returncode == 0, r.stderr
    b = read_exr_rgba(tmp_path / "b.exr").reshape(SIZE[1], 4, SIZE[0])
    assert np.array_equal(b[:, 3, :], coarse[..., 0])


def test_progressive_state_advances_one_pass_at_a_time(blobs):
    # the state behind the generator is one thread at a time (progressive.h): a second thread's
    # pass is refused, never run beside the first (two at once would repeat or skip passes)
    import threading
    from wvol import _wvol
    opts = dict(camera="+z", width=SIZE[0], height=SIZE[1], mode="xray", tf="gaussian", tf_units="world",
                step=None, termination=None, threads=1)
    ref = {info["index"]: img for img, _, info in wvol.render_progressive(blobs, "+z", SIZE, mode="xray",
                                                                          threads=1)}
    for _ in range(5):
        state = _wvol.progressive_begin(blobs.data, blobs.spacing, blobs.origin, "db2", None, 0.0, 0.0, 4.0, 1)
        got, refused, lock, done = [], [], threading.Lock(), threading.Event()

        def advance():
            while not done.is_set():
                try:
                    img, _, info = _wvol.progressive_next(state, opts)
                except RuntimeError as e:
                    with lock:
                        refused.append(str(e))
                    continue
                except ValueError as e:   # the other thread rendered the last pass meanwhile
                    assert "last pass" in str(e)
                    return
                with lock:
                    got.append((info["index"], img))
                if info["last"]:
                    done.set()

        threads = [threading.Thread(target=advance) for _ in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert sorted(k for k, _ in got) == sorted(ref), (len(got), refused[:1])
        assert all(np.array_equal(img, ref[k]) for k, img in got)
        assert all("another thread" in m for m in refused)
