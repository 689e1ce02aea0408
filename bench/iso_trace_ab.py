#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""The exact f^ tracer (`wvol iso --method raytrace`) of two or more wvol builds on the same
image, alternated round by round in one run, one thread: the process CPU seconds of each trace
(`trace_cpu_seconds`, steadier than wall time on a shared machine), hits and functions.

Usage: /usr/bin/python3 bench/iso_trace_ab.py VOLUME ISO SIZE KEEP ROUNDS WVOL [WVOL ...]
  (a raw float32 VOLUME of n^3 samples: VOLUME=path.raw@n)
  e.g. bench/iso_trace_ab.py skull.nrrd 400 128x128 5% 2 /path/to/main/build/wvol build/wvol
A WVOL may carry environment settings for its runs: path:NAME=VALUE[:NAME=VALUE].
Prints per build the fastest CPU seconds and every round's, the ratio of the first build's to
its, and whether its image is the first build's (pixels whose hit differs, largest depth
difference where both hit; EXR Z); bench/results/iso_trace_profile.md quotes its output."""
import json
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_render import read_exr  # noqa: E402

CAMERA = "persp dir=1,0.6,-0.3"


def main():
    if len(sys.argv) < 7:
        sys.exit(__doc__)
    vol, iso, size, keep, rounds = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5])
    dims = []
    if "@" in vol:
        vol, n = vol.rsplit("@", 1)
        dims = ["--dims", n]
    builds = sys.argv[6:]
    res = {b: [] for b in builds}
    depth = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(rounds):
            for i, b in enumerate(builds):
                path, *envs = b.split(":")
                env = dict(os.environ)
                env.update(dict(e.split("=", 1) for e in envs))
                out = subprocess.run([path, "iso", vol, *dims, "--method", "raytrace", "--iso", iso, "--keep", keep,
                                      "--camera", CAMERA, "--size", size, "--threads", "1",
                                      "-o", os.path.join(tmp, f"image{i}.exr"), "--json"],
                                     capture_output=True, text=True, env=env, check=True)
                j = json.loads(out.stdout)
                res[b].append((j["trace_cpu_seconds"], j["hits"], j["functions"]))
                if b not in depth:
                    depth[b] = read_exr(os.path.join(tmp, f"image{i}.exr"))["Z"]
    z0 = depth[builds[0]]
    h0 = np.isfinite(z0) & (z0 < 1e30)
    c0 = min(x[0] for x in res[builds[0]])
    for b in builds:
        c = [x[0] for x in res[b]]
        z = depth[b]
        h = np.isfinite(z) & (z < 1e30)
        both = h & h0
        dz = float(np.abs(z[both] - z0[both]).max()) if both.any() else 0.0
        print(f"{b:40s} CPU s {min(c):.3f} (rounds: {' '.join(f'{x:.2f}' for x in c)}) ratio {c0 / min(c):.2f} "
              f"hits {res[b][0][1]} functions {res[b][0][2]}; vs first: {int((h != h0).sum())} pixels differ in hit, "
              f"depth max diff {dz:.3g}")


if __name__ == "__main__":
    main()
