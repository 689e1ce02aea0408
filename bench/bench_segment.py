#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Segmentation benchmark (issue 9): wavelet features + 3D Kohonen map against plain
intensity and against k-means (scikit-learn) on the same wavelet features, on the
texture mosaics of datasets-synth. Error = misclassification after mapping each cluster
to its majority class, overall and away from boundaries; time per method. Writes
bench/results/segment.json and PNG label maps next to the ground truth.

usage: bench/bench_segment.py [--size 256] [--quick]
"""
import argparse
import json
import os
import pathlib
import subprocess
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
WVOL = os.environ.get("WVOL_BIN", str(ROOT / "build" / "wvol"))
OUT = ROOT / "bench" / "results"


def run(*args):
    r = subprocess.run([WVOL, *map(str, args)], capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"wvol {' '.join(map(str, args))}: {r.stderr.strip()}")
    return r.stdout


def majority_error(pred, truth, interior):
    pred = pred.astype(np.int64).ravel()
    truth = truth.astype(np.int64).ravel()
    table = np.zeros((pred.max() + 1, truth.max() + 1), np.int64)
    np.add.at(table, (pred, truth), 1)
    mapped = table.argmax(axis=1)[pred]
    bad = mapped != truth
    return float(bad.mean()), float(bad[interior.ravel()].mean())


def interior_mask(truth, r):
    """Pixels whose (2r+1)^2 window holds one class (same rule as wvol_segmentation_score)."""
    from scipy.ndimage import maximum_filter, minimum_filter
    return maximum_filter(truth, size=2 * r + 1, mode="nearest") == minimum_filter(truth, size=2 * r + 1,
                                                                                   mode="nearest")


def kmeans(x, k, seed=1):
    from sklearn.cluster import KMeans
    t = time.perf_counter()
    lab = KMeans(n_clusters=k, n_init=3, random_state=seed).fit_predict(x)
    return lab, time.perf_counter() - t


def save_png(path, labels):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plt.imsave(path, labels, cmap="tab20", vmin=0, vmax=19)


def main():
    global OUT  # --out moves the results
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--quick", action="store_true", help="one family and depth (smoke run)")
    ap.add_argument("--out", default=str(OUT), help="folder for segment.json and the images (default bench/results)")
    args = ap.parse_args()
    OUT = pathlib.Path(args.out)
    n = args.size
    OUT.mkdir(parents=True, exist_ok=True)
    families = ["db2"] if args.quick else ["haar", "db2", "coif1", "bl3"]
    depths = [3] if args.quick else [2, 3, 4]
    variants = ["gratings"] if args.quick else ["gratings", "frequencies", "mixed"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for variant in variants:
            img, lab = tmp / f"{variant}.raw", tmp / f"{variant}_labels.raw"
            run("synth", "textures", "-o", img, "--size", f"{n}x{n}x1", "--variant", variant, "--labels", lab)
            x = np.fromfile(img, "<f4").reshape(n, n)
            truth = np.fromfile(lab, "<f4").reshape(n, n).astype(np.int32)
            k = int(truth.max()) + 1
            save_png(OUT / f"segment_{variant}_truth.png", truth)
            # plain intensity: k-means on the pixel value alone
            lab_i, t_i = kmeans(x.reshape(-1, 1), k)
            for fam in families:
                for m in depths:
                    interior = interior_mask(truth, 2 ** m)
                    e_int = majority_error(lab_i, truth, interior)
                    pred, feat = tmp / "pred.raw", tmp / "feat.raw"
                    t0 = time.perf_counter()
                    run("segment", img, "--dims", f"{n}x{n}x1", "--wavelet", fam, "--levels", m, "--som", "4x4x4",
                        "-o", pred, "--features-out", feat)
                    t_som = time.perf_counter() - t0
                    p = np.fromfile(pred, "<f4").reshape(n, n).astype(np.int32)
                    e_som = majority_error(p, truth, interior)
                    f = np.fromfile(feat, "<f4").reshape(-1, n * n).T
                    lab_k, t_k = kmeans(f, k)
                    e_k = majority_error(lab_k, truth, interior)
                    # k-means with as many clusters as the map has neurons, for a like-for-like count
                    lab_k64, t_k64 = kmeans(f, 64)
                    e_k64 = majority_error(lab_k64, truth, interior)
                    if m == 3:
                        save_png(OUT / f"segment_{variant}_{fam}_som.png", p)
                        save_png(OUT / f"segment_{variant}_{fam}_kmeans.png", lab_k.reshape(n, n))
                    row = dict(variant=variant, wavelet=fam, levels=m, size=n,
                               som_error=e_som[0], som_error_interior=e_som[1], som_seconds=t_som,
                               kmeans_error=e_k[0], kmeans_error_interior=e_k[1], kmeans_seconds=t_k,
                               kmeans64_error=e_k64[0], kmeans64_error_interior=e_k64[1],
                               kmeans64_seconds=t_k64,
                               intensity_error=e_int[0], intensity_error_interior=e_int[1],
                               intensity_seconds=t_i)
                    rows.append(row)
                    print(f"{variant:11s} {fam:5s} M={m}  SOM {100*e_som[1]:5.1f}% interior "
                          f"({100*e_som[0]:5.1f}% all, {t_som:5.2f}s) | k-means(k={k}) {100*e_k[1]:5.1f}% "
                          f"({t_k:5.2f}s) | k-means(64) {100*e_k64[1]:5.1f}% | intensity {100*e_int[1]:5.1f}%",
                          flush=True)
    best = min((r for r in rows if r["variant"] == "gratings"), key=lambda r: r["som_error_interior"])
    summary = dict(best_gratings=best, goal="under 5% away from boundaries for the sine-grating compositions")
    (OUT / "segment.json").write_text(json.dumps(dict(rows=rows, summary=summary), indent=1))
    print(f"best on gratings: {best['wavelet']} M={best['levels']}: "
          f"{100*best['som_error_interior']:.2f}% away from boundaries; wrote {OUT/'segment.json'}")


if __name__ == "__main__":
    main()
