# SPDX-License-Identifier: MIT
"""Our NRRD files as VTK (and so ParaView) reads them: vtkNrrdReader must see the
same dimensions, spacing, origin and samples as the raw float32 file of the same
volume. (vtkNrrdReader reads a fastest axis of 9 or fewer samples as vector
components, a guess of its own, so the x size here is larger than that.)"""
import numpy as np
import pytest

import vtkmodules.vtkIOImage as vtk_image  # noqa: E402  (python3-vtk9: part of the setup)
from vtkmodules.util.numpy_support import vtk_to_numpy  # noqa: E402

DIMS = (23, 17, 11)
SPACING = (0.5, 0.75, 1.25)


def read_vtk(path):
    r = vtk_image.vtkNrrdReader()
    r.SetFileName(str(path))
    r.Update()
    im = r.GetOutput()
    return im, vtk_to_numpy(im.GetPointData().GetScalars())


@pytest.mark.parametrize("name,extra", [("v.nrrd", []), ("v.nhdr", []), ("g.nrrd", ["--gzip"]),
                                        ("g.nhdr", ["--gzip"])])
@pytest.mark.parametrize("kind", ["skull", "blobs"])
def test_vtk_reads_our_nrrd(wvol, tmp_path, name, extra, kind):
    size = "x".join(map(str, DIMS))
    spacing = ",".join(map(str, SPACING))
    raw, nrrd = tmp_path / "ref.raw", tmp_path / name
    for out, more in ((raw, []), (nrrd, extra)):
        r = wvol("synth", kind, "-o", out, "--size", size, "--spacing", spacing, "--seed", "3", *more)
        assert r.returncode == 0, r.stderr
    ref = np.fromfile(raw, "<f4")
    im, values = read_vtk(nrrd)
    assert im.GetDimensions() == DIMS
    assert im.GetNumberOfScalarComponents() == 1
    assert im.GetSpacing() == pytest.approx(SPACING, abs=0)
    expect_origin = [-(n - 1) / 2 * s for n, s in zip(DIMS, SPACING)]
    assert im.GetOrigin() == pytest.approx(expect_origin, abs=0)
    assert values.dtype == np.float32
    assert np.array_equal(values.ravel(), ref)


def test_vtk_and_wvol_agree_on_a_skull(wvol, tmp_path):
    """The 128^3 phantom the demo writes, as VTK sees it: HU range and geometry."""
    out = tmp_path / "demo"
    assert wvol("demo", "--out", out).returncode == 0
    im, values = read_vtk(out / "skull.nrrd")
    assert im.GetDimensions() == (128, 128, 128)
    assert im.GetSpacing() == pytest.approx((1.875,) * 3)
    assert values.min() == -1000 and 1700 <= values.max() <= 1800  # air; cortical bone and teeth 1750-1800
