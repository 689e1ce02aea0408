# SPDX-License-Identifier: MIT
"""Robustness of the extension: every entry point refuses bad arrays with an exception
(never a crash), releases the GIL safely (concurrent calls agree with serial ones), and
hands buffers over without leaking or aliasing."""
import concurrent.futures as cf
import gc

import numpy as np
import pytest

import wvol

GOOD = np.random.default_rng(0).random((8, 8, 8), dtype=np.float32)

BAD_ARRAYS = [  # (array, exception, what its message says)
    (np.zeros((8, 8, 8), complex), TypeError, "expected an array of real numbers"),
    (np.array([["a", "b"]]), TypeError, "expected an array of real numbers"),
    (np.zeros((8, 8, 8), object), TypeError, "expected an array of real numbers"),
    (np.zeros(8, np.float32), ValueError, "got 1 dimensions"),
    (np.zeros((2, 2, 2, 2), np.float32), ValueError, "got 4 dimensions"),
    (np.zeros((0, 8, 8), np.float32), ValueError, "the array is empty"),
    (np.full((8, 8, 8), np.nan, np.float32), ValueError, r"NaN at voxel \(i=0, j=0, k=0\)"),
    (np.full((8, 8, 8), np.inf), ValueError, r"Inf at voxel \(i=0, j=0, k=0\)"),  # float64
    (None, TypeError, "expected an array of real numbers"),
]

ENTRY_POINTS = {
    "save": lambda a, tmp: wvol.save(a, tmp / "x.raw"),
    "dwt3": lambda a, tmp: wvol.dwt3(a, "haar", 1),
    "compress": lambda a, tmp: wvol.compress(a, "haar", 1, keep=0.5),
    "segment": lambda a, tmp: wvol.segment(a, levels=1, iterations=10),
    "features": lambda a, tmp: wvol.features(a, levels=1),
    "idwt3": lambda a, tmp: wvol.idwt3(wvol.Coeffs(a, "haar", 1, (8, 8, 8))),
    "render": lambda a, tmp: wvol.render(a, size=(4, 4)),
    "isosurface": lambda a, tmp: wvol.isosurface(a, 0.5),
}


@pytest.mark.parametrize("name", sorted(ENTRY_POINTS))
@pytest.mark.parametrize("arr, exc, words", BAD_ARRAYS, ids=[f"bad{i}" for i in range(len(BAD_ARRAYS))])
def test_entry_points_refuse_bad_arrays(name, arr, exc, words, tmp_path):
    with pytest.raises(exc, match=words):
        ENTRY_POINTS[name](arr, tmp_path)


@pytest.mark.parametrize("name", sorted(ENTRY_POINTS))
def test_entry_points_accept_views_and_other_dtypes(name, tmp_path):
    """Non-contiguous views, Fortran order, float64 and integers are converted, not refused."""
    base = np.random.default_rng(1).random((16, 8, 16))
    for a in (base[::2, :, ::2], np.asfortranarray(base[:8, :, :8]), (base[:8, :, :8] * 100).astype(np.int16),
              base[:8, :, :8].astype(np.float32)[::-1]):
        ENTRY_POINTS[name](a, tmp_path)


def test_views_give_the_same_result_as_copies():
    base = np.random.default_rng(2).random((16, 16, 16), dtype=np.float32)
    view = base[::2, ::-2, 1::2]
    a = wvol.compress(view, "db2", 2, keep=0.2).reconstruct().data
    b = wvol.compress(np.ascontiguousarray(view), "db2", 2, keep=0.2).reconstruct().data
    assert np.array_equal(a, b)


def test_concurrent_calls_match_serial():
    """The GIL is released inside the library: threads run at once and must agree."""
    vols = [wvol.synth.blobs(shape=(24, 24, 24), seed=s) for s in range(4)]

    def work(v):
        s = wvol.compress(v, "db2", 3, keep=0.05)
        return s.reconstruct().data, s.predicted_error.l2

    serial = [work(v) for v in vols]
    with cf.ThreadPoolExecutor(4) as ex:
        parallel = list(ex.map(work, vols))
    for (a, ea), (b, eb) in zip(serial, parallel):
        assert np.array_equal(a, b) and ea == eb


def test_concurrent_render_isosurface_and_files_match_serial(tmp_path):
    """Rendering, marching cubes and .wvc files release the GIL too; threads must agree."""
    vols = [wvol.synth.blobs(shape=(16, 16, 16), seed=s) for s in range(4)]

    def work(i):
        s = wvol.compress(vols[i], "db2", 2, keep=0.1)
        s.save(tmp_path / f"{i}.wvc")
        o = wvol.open(tmp_path / f"{i}.wvc")
        return (wvol.render(o, size=(6, 6), camera="persp dir=1,1,1"),
                wvol.render(vols[i], size=(16, 16)), *wvol.isosurface(o, 0.2)[:2])

    serial = [work(i) for i in range(4)]
    with cf.ThreadPoolExecutor(4) as ex:
        parallel = list(ex.map(work, range(4)))
    for a, b in zip(serial, parallel):
        assert all(np.array_equal(x, y) for x, y in zip(a, b))


def test_handed_over_buffers_outlive_their_owners():
    c = wvol.dwt3(GOOD, "haar", 1)
    data = c.data
    del c
    gc.collect()
    assert np.abs(wvol.idwt3(wvol.Coeffs(data, "haar", 1, (8, 8, 8))) - GOOD).max() < 1e-6
    s = wvol.compress(GOOD, "haar", 1)
    rec = s.reconstruct().data
    rec[:] = 0                                       # writable, and not aliasing the store
    assert np.abs(s.reconstruct().data - GOOD).max() < 1e-6


@pytest.mark.parametrize("bad, exc, words", [
    (lambda: wvol.load(123), TypeError, "os.PathLike"),
    (lambda: wvol.load("/nonexistent/dir/x.nrrd"), OSError, "No such file"),
    (lambda: wvol.save(GOOD, "/nonexistent/dir/x.raw"), OSError, "cannot create"),
    (lambda: wvol.save(GOOD, "/tmp/x.unknown-extension"), NotImplementedError, "cannot write this format"),
    (lambda: wvol.idwt3(wvol.Coeffs(GOOD, "haar", 1, (9, 8, 8))), ValueError, "padded size"),
    (lambda: wvol.idwt3(wvol.Coeffs(GOOD, "haar", 0, (8, 8, 8))), ValueError, "levels"),
    (lambda: wvol.idwt3(wvol.Coeffs(GOOD, "haar", 1, (8, 8))), TypeError, "shape"),
])
def test_bad_files_and_metadata_raise_with_the_message(bad, exc, words):
    with pytest.raises(exc, match=words):
        bad()


def test_float32_c_order_input_is_not_copied():
    """NumPy reports its allocations to tracemalloc; the library's own buffers are not
    traced. Reading a float32 C-order array must allocate no copy of it (1 MiB here), a
    float64 one must (the conversion), so the peak tells the two apart."""
    import tracemalloc
    a32 = np.random.default_rng(3).random((64, 64, 64), dtype=np.float32)
    a64 = a32.astype(np.float64)
    wvol.dwt3(a32, "haar", 1)                      # warm up (filter tables, imports)

    def peak(arr):
        tracemalloc.start()
        c = wvol.dwt3(arr, "haar", 1)
        p = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        del c
        return p

    assert peak(a32) < 64 * 1024
    assert peak(a64) >= a32.nbytes
