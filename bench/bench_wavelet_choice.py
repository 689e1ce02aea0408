#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Calibration of `wvol compress --wavelet auto`: the trial's bit estimates against real file sizes.

For each volume and PSNR target, `wvol compress` runs once with the default (auto: the trial's
estimates per candidate, the filter chosen, the trial's wall time, from --json) and once with
each candidate named (db2, db4, coif2, haar: the real bits per voxel). What the choice needs is
the ratio of a candidate's bits to db2's, so the table gives both ratios (estimated and real)
and the estimate's error on it; and whether the filter chosen is the one with the fewest real
bits among those more than the margin below db2 (else db2).

Volumes (`wvol synth`, raw in /dev/shm): the noisy skull (noise 20 HU), the turbulence field,
the Gaussian, Shepp-Logan, and white noise (numpy, seed 1).

  python3 bench/bench_wavelet_choice.py [--size 256] [--targets 40,50,60]
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from benchutil import cpu_model  # noqa: E402

CANDIDATES = ("db2", "db4", "coif2", "haar")


def compress(wvol, raw, dims, psnr, out, env, wavelet=None):
    cmd = [wvol, "compress", raw, "--dims", dims, "--psnr", str(psnr), "-o", out, "--json", "--threads", "1"]
    if wavelet:
        cmd += ["--wavelet", wavelet]
    p = subprocess.run([str(c) for c in cmd], env=env, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"wvol compress failed: {p.stderr.strip()}")
    return json.loads(p.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--targets", default="40,50,60")
    ap.add_argument("--wvol", default=os.environ.get("WVOL_BIN", str(ROOT / "build" / "wvol")))
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "wavelet_choice"))
    a = ap.parse_args()
    n, wvol = a.size, a.wvol
    dims = f"{n}x{n}x{n}"
    env1 = dict(os.environ, OMP_NUM_THREADS="1", OMP_WAIT_POLICY="passive")
    tmp = Path(tempfile.mkdtemp(prefix="bench_wchoice_", dir="/dev/shm" if os.path.isdir("/dev/shm") else None))
    rows = []
    try:
        for kind, extra in (("skull", ["--noise", "20"]), ("turbulence", []), ("gaussian", []),
                            ("shepp-logan", []), ("noise", None)):
            raw = tmp / f"{kind}.raw"
            if extra is None:
                np.random.default_rng(1).standard_normal(n ** 3).astype("<f4").tofile(raw)
            else:
                subprocess.run([wvol, "synth", kind, "--size", str(n), *extra, "-o", raw], check=True,
                               stdout=subprocess.DEVNULL)
            for t in [float(x) for x in a.targets.split(",")]:
                auto = compress(wvol, raw, dims, t, tmp / "a.wvc", env1)
                ch = auto["wavelet_choice"]
                real = {w: compress(wvol, raw, dims, t, tmp / "b.wvc", env1, w)["bits_per_voxel"] for w in CANDIDATES}
                est = ch["bits_per_coefficient"]
                below = [w for w in CANDIDATES[1:] if real[w] < (1 - ch["margin"]) * real["db2"]]
                ideal = min(below, key=lambda w: real[w]) if below else "db2"
                row = {"volume": kind, "size": n, "target_db": t, "chosen": ch["chosen"], "ideal": ideal,
                       "margin": ch["margin"], "trial_seconds": ch["seconds"], "sample_voxels": ch["sample_voxels"],
                       "compress_seconds": auto["seconds"]["encode"], "bits_auto": auto["bits_per_voxel"],
                       "estimated": est, "real": real}
                rows.append(row)
                print(f"{kind} {t:g} dB: chose {ch['chosen']} (ideal {ideal}); " + "; ".join(
                    f"{w} est {est[w]:.4f} real {real[w]:.4f}" for w in CANDIDATES), flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    meta = {"machine": cpu_model(), "date": time.strftime("%Y-%m-%d %H:%M"), "wvol": str(wvol), "rows": rows}
    out = Path(a.out)
    out.with_suffix(".json").write_text(json.dumps(meta, indent=1) + "\n")
    L = [f"# `--wavelet auto`: the trial's estimates against real file sizes ({n}^3)", "",
         f"{meta['machine']}; {meta['date']}. Made by `bench/bench_wavelet_choice.py`: per volume and target, "
         "`wvol compress --psnr T` with the default (auto) and with each candidate named, one thread. "
         "est = the trial's estimated bits per sampled coefficient; real = the file's bits per voxel. The "
         "choice uses est / est(db2) (db2 unless another is below 1 - margin); \"ideal\" applies the same rule "
         "to the real sizes. Ratio error = est ratio / real ratio - 1.", "",
         "| volume | dB | chosen | ideal | " + " | ".join(f"{w} est / real" for w in CANDIDATES) + " | " +
         " | ".join(f"{w}/db2 est / real (error)" for w in CANDIDATES[1:]) + " |",
         "|---|---|---|---|" + "---|" * (2 * len(CANDIDATES) - 1)]
    for r in rows:
        e, q = r["estimated"], r["real"]
        cells = [f"{e[w]:.4f} / {q[w]:.4f}" for w in CANDIDATES]
        rat = []
        for w in CANDIDATES[1:]:
            if e["db2"] > 0:
                re_, rr = e[w] / e["db2"], q[w] / q["db2"]
                rat.append(f"{re_:.3f} / {rr:.3f} ({100 * (re_ / rr - 1):+.0f}%)")
            else:
                rat.append(f"- / {q[w] / q['db2']:.3f}")
        L.append(f"| {r['volume']} | {r['target_db']:g} | {r['chosen']} | {r['ideal']} | " + " | ".join(cells) +
                 " | " + " | ".join(rat) + " |")
    agree = sum(r["chosen"] == r["ideal"] for r in rows)
    L += ["", f"The choice equals the ideal one on {agree} of {len(rows)} rows."]
    out.with_suffix(".md").write_text("\n".join(L) + "\n")
    print(f"wrote {out.with_suffix('.md')} and .json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
