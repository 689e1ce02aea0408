#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""How tight is a per-pixel error bound, and what does progressive rendering buy.

Part 1, bound against actual error. Volumes: the Gaussian, the skull phantom and the skull with
CT-like noise (sigma --noise HU), at --size^3 (db2, 3 levels), kept fractions --keep. For each,
in this one run, through the wvol Python module:
  actual  |image of all coefficients - image of the kept ones| per pixel, both from the exact
          paths (axis for views along an axis, spline otherwise), so that the difference is the
          compression's alone;
  bound   wvol.render(..., bound=True) from the same store (docs/render.md, "Error bounds").
Views: X-ray along +z (axis, --size^2 pixels), X-ray oblique ("ortho dir=1,0.6,0.3", spline, at
--small^3 and --small-image^2: the spline path costs minutes at full size) and absorption along +z
with the gaussian preset (spline, also small). Per row: the distribution of bound / actual over
the pixels where the actual error is above 1e-6 of the largest (percentiles, the fraction of
pixels where the bound is within 2x), and the smallest ratio, which must be >= 1.
Peer: ZFP in fixed-accuracy mode (zfpy, serial) at the tolerance whose decoded volume has the
RMSE of the kept store (bisection on the tolerance), on the same volume. The per-pixel bound a
ZFP user can state is tolerance x the ray's length (every voxel, and so every trilinear sample,
is within the tolerance): its ratio to ZFP's actual X-ray error (the dense reference integrator
on both volumes, same camera) is listed beside ours.

Part 2, progressive rendering: wvol.render_progressive (X-ray along +z, growth --growth) on the
same volumes at --size^3; per pass the elapsed time, the bound (max, mean) and the actual error
(max, mean) against the image of all coefficients.

Part 3, a .wvc file's quantiser term: each volume at --size^3 compressed to --psnr dB with
`wvol compress` (every coefficient kept, so the bound is the quantiser's alone), then
`wvol render FILE.wvc --mode xray --camera +z --bound` (its JSON's bound_max) against the actual
largest pixel error of the file's image (wvol.open) to the image of all the unquantised
coefficients (same family and levels). --only-wvc runs this part alone and adds it to an existing
bound.json.

Writes bench/results/bound.json, bound.md and bound.png. Smoke run: bench/bench_bound.py --size 32
--small 16; the real one: bench/bench_bound.py (defaults).
"""
import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import benchutil  # noqa: E402

import wvol  # noqa: E402

RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")


def volumes(n, noise):
    return {
        "gaussian": wvol.synth.gaussian(shape=(n, n, n)),
        "skull": wvol.synth.skull(shape=(n, n, n)),
        "skull-noisy": wvol.synth.skull(shape=(n, n, n), noise=noise),
    }


def ratio_stats(actual, bound, magnitude):
    """bound / actual over the pixels whose actual error is above the float32 rounding of the two
    images (2^-23 of the pixel's magnitude: below it the difference is rounding, not compression);
    violations: pixels where the bound is below the actual error beyond that rounding."""
    a = actual.ravel().astype(np.float64)
    b = bound.ravel().astype(np.float64)
    rounding = 2.0 ** -23 * magnitude.ravel().astype(np.float64)
    mask = a > 4 * rounding + 1e-300
    out = {"pixels": int(mask.sum()), "violations": int(np.sum(b + rounding < a)),
           "bound_max": float(b.max()), "actual_max": float(a.max())}
    if not mask.any():
        return out
    r = b[mask] / a[mask]
    out.update({"min": float(r.min()), "p50": float(np.percentile(r, 50)), "p90": float(np.percentile(r, 90)),
                "p99": float(np.percentile(r, 99)), "max": float(r.max()), "within_2x": float(np.mean(r <= 2.0))})
    return out


def zfp_matching(v, target_rmse):
    """ZFP fixed-accuracy at the tolerance whose decoded RMSE is close to target_rmse (from below)."""
    import zfpy
    lo, hi = 1e-6 * float(np.ptp(v)), float(np.ptp(v))
    best = None
    for _ in range(30):
        tol = (lo * hi) ** 0.5
        d = zfpy.decompress_numpy(zfpy.compress_numpy(v, tolerance=tol))
        rmse = float(np.sqrt(np.mean((d.astype(np.float64) - v) ** 2)))
        if rmse <= target_rmse:
            lo, best = tol, (tol, d, rmse)
        else:
            hi = tol
        if hi / lo < 1.05:
            break
    return best


def chord_lengths(v, camera, size):
    """World length of each pixel's ray inside the box, from an X-ray of a volume of ones."""
    ones = wvol.Volume(np.ones_like(v.data), v.spacing, v.origin)
    img = wvol.render(ones, camera, size, mode="xray", method="reference", step=0.25)
    return img[..., 0].astype(np.float64)


def part1(args):
    rows = []
    keeps = [float(k) / 100 for k in args.keep.split(",")]
    views = [("xray +z", "+z", "xray", "auto", False), ("xray oblique", "ortho dir=1,0.6,0.3", "xray", "spline", True),
             ("absorption +z", "+z", "absorption", "spline", True)]
    for small in (False, True):
        n = args.small if small else args.size
        img = (args.small_image,) * 2 if small else (n, n)
        for name, v in volumes(n, args.noise).items():
            full = wvol.compress(v)
            for keep in keeps:
                t0 = time.time()
                st = wvol.compress(v, keep=keep, residual=True)
                for view, cam, mode, method, is_small in views:
                    if is_small != small:
                        continue
                    tf = "gaussian"
                    ia = wvol.render(full, cam, img, mode=mode, method=method, tf=tf)
                    ik, bd, s = wvol.render(st, cam, img, mode=mode, method=method, tf=tf, bound=True,
                                            return_stats=True)
                    ch = slice(0, 3)
                    actual = np.abs(ia[..., ch].astype(np.float64) - ik[..., ch]).max(axis=-1)
                    mag = np.abs(ia[..., ch]).max(axis=-1) + np.abs(ik[..., ch]).max(axis=-1)
                    row = {"volume": name, "n": n, "image": img[0], "keep": keep, "view": view, "method": s["method"],
                           "ours": ratio_stats(actual, bd[..., ch].max(axis=-1), mag)}
                    if mode == "xray":
                        t1 = time.time()
                        _, bc = wvol.render(st, cam, img, mode=mode, tf=tf, bound="coarse")
                        row["coarse_seconds"] = time.time() - t1
                        row["coarse"] = ratio_stats(actual, bc[..., 0], mag)
                    if mode == "xray" and not small:
                        zm = zfp_matching(v.data, st.report["predicted_rmse"])
                        if zm:
                            tol, d, rmse = zm
                            za = wvol.render(v, cam, img, mode="xray", method="reference")
                            zd = wvol.render(wvol.Volume(d, v.spacing, v.origin), cam, img, mode="xray",
                                             method="reference")
                            zact = np.abs(za[..., 0].astype(np.float64) - zd[..., 0])
                            zbound = tol * chord_lengths(v, cam, img)
                            zmag = np.abs(za[..., 0]) + np.abs(zd[..., 0])
                            row["zfp"] = {"tolerance": tol, "rmse": rmse, **ratio_stats(zact, zbound, zmag)}
                    row["seconds"] = time.time() - t0
                    rows.append(row)
                    o = row["ours"]
                    z = row.get("zfp", {})
                    print(f"{name:12s} {n:4d}^3 keep {keep:5.1%} {view:14s} ({row['method']}): bound/actual "
                          f"p50 {o.get('p50', float('nan')):.2f} p90 {o.get('p90', float('nan')):.2f} "
                          f"min {o.get('min', float('nan')):.3f} within2x {o.get('within_2x', float('nan')):.2f} "
                          f"violations {o['violations']}"
                          + (f" | zfp p50 {z['p50']:.1f} min {z['min']:.2f}" if z.get('pixels') else ""), flush=True)
    return rows


def part2(args):
    out = []
    for name, v in volumes(args.size, args.noise).items():
        full = wvol.render(wvol.compress(v), "+z", (args.size, args.size), mode="xray")
        passes = []
        for img, bd, info in wvol.render_progressive(v, "+z", (args.size, args.size), mode="xray",
                                                     growth=args.growth):
            act = np.abs(full[..., 0].astype(np.float64) - img[..., 0])
            passes.append({"index": info["index"], "kept": info["kept"], "total": info["total"],
                           "elapsed": info["elapsed"], "seconds": info["seconds"], "method": info["method"],
                           "bound_max": info["bound_max"], "bound_mean": info["bound_mean"],
                           "actual_max": float(act.max()), "actual_mean": float(act.mean()),
                           "holds": bool(np.all(act <= bd[..., 0].astype(np.float64) * (1 + 1e-6) +
                                                2.0 ** -23 * np.abs(full[..., 0])))})
            p = passes[-1]
            print(f"progressive {name:12s} pass {p['index']}: {p['kept']:9d} kept, {p['elapsed']:.3f} s, bound max "
                  f"{p['bound_max']:.4g} actual max {p['actual_max']:.4g} holds {p['holds']}", flush=True)
        out.append({"volume": name, "n": args.size, "passes": passes})
    return out


def part3(args):
    import subprocess
    import tempfile
    wv = os.environ.get("WVOL_BIN", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build", "wvol"))
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, v in volumes(args.size, args.noise).items():
            src = os.path.join(tmp, name + ".nrrd")
            wvol.save(v, src)
            for psnr in [float(x) for x in args.psnr.split(",")]:
                f = os.path.join(tmp, f"{name}_{psnr:.0f}.wvc")
                subprocess.run([wv, "compress", src, "-o", f, "--psnr", str(psnr)], check=True, capture_output=True)
                r = subprocess.run([wv, "render", f, "-o", os.path.join(tmp, "x.exr"), "--mode", "xray", "--camera",
                                    "+z", "--size", f"{args.size}x{args.size}", "--bound", os.path.join(tmp, "b.exr"),
                                    "--json"], check=True, capture_output=True, text=True)
                info = json.loads(r.stdout)
                st = wvol.open(f)
                levels = wvol.wvc_info(f)["levels"]
                full = wvol.render(wvol.compress(v, levels=levels), "+z", (args.size, args.size), mode="xray")
                img = wvol.render(st, "+z", (args.size, args.size), mode="xray")
                act = float(np.abs(full[..., 0].astype(np.float64) - img[..., 0]).max())
                out.append({"volume": name, "n": args.size, "psnr": psnr, "coeff_error": info["bound_coeff_error"],
                            "bound_max": info["bound_max"], "actual_max": act,
                            "ratio_max": info["bound_max"] / act if act > 0 else None})
                print(f"wvc {name:12s} {psnr:.0f} dB: coefficient error {info['bound_coeff_error']:.4g}, bound max "
                      f"{info['bound_max']:.4g}, actual max {act:.4g}", flush=True)
    return out


def write(args, rows, prog, wvc=()):
    os.makedirs(RESULTS, exist_ok=True)
    doc = {"machine": benchutil.cpu_model(), "args": vars(args), "bound_vs_actual": rows, "progressive": prog,
           "wvc_quantiser": list(wvc)}
    with open(os.path.join(RESULTS, "bound.json"), "w") as f:
        json.dump(doc, f, indent=1)
    lines = ["# Per-pixel error bounds: bound against actual error, and progressive rendering", "",
             f"Machine: {doc['machine']}. Generated by `bench/bench_bound.py` "
             f"(size {args.size}, small {args.small}/{args.small_image}, noise {args.noise}).", "",
             "Ratio = bound / actual per pixel (pixels with an actual error above 1e-6 of the largest); "
             "min >= 1 means the bound held on every pixel. ZFP: fixed accuracy at the RMSE of the kept store, "
             "bound = tolerance x ray length.", "",
             "Coarse: the O(1)-a-pixel bound (each band's largest dropped coefficient). Violations: pixels where "
             "the bound is below the actual error beyond the images' float32 rounding (must be 0).", "",
             "| volume | n | keep | view | path | violations | min | p50 | p90 | p99 | within 2x | coarse p50 | "
             "ZFP min | ZFP p50 | ZFP p90 |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        o, z = r["ours"], r.get("zfp", {})
        f = lambda d, k: f"{d[k]:.3g}" if d.get("pixels") else "-"  # noqa: E731
        c = r.get("coarse", {})
        lines.append(f"| {r['volume']} | {r['n']} | {r['keep']:.0%} | {r['view']} | {r['method']} | {o['violations']} | "
                     f"{f(o, 'min')} | {f(o, 'p50')} | {f(o, 'p90')} | {f(o, 'p99')} | {f(o, 'within_2x')} | "
                     f"{f(c, 'p50')} | {f(z, 'min')} | {f(z, 'p50')} | {f(z, 'p90')} |")
    lines += ["", "## Progressive rendering (X-ray along +z)", "",
              "| volume | pass | kept | elapsed s | bound max | actual max | bound mean | actual mean | holds |",
              "|---|---|---|---|---|---|---|---|---|"]
    for p in prog:
        for q in p["passes"]:
            lines.append(f"| {p['volume']} | {q['index']} | {q['kept']} | {q['elapsed']:.3f} | {q['bound_max']:.4g} | "
                         f"{q['actual_max']:.4g} | {q['bound_mean']:.4g} | {q['actual_mean']:.4g} | {q['holds']} |")
    lines += ["", "## A .wvc file's quantiser term (every coefficient kept; X-ray along +z)", "",
              "| volume | n | PSNR dB | coefficient error | bound max | actual max | bound max / actual max |",
              "|---|---|---|---|---|---|---|"]
    for q in wvc:
        lines.append(f"| {q['volume']} | {q['n']} | {q['psnr']:.0f} | {q['coeff_error']:.4g} | {q['bound_max']:.4g} | "
                     f"{q['actual_max']:.4g} | {q['ratio_max'] or float('nan'):.0f} |")
    with open(os.path.join(RESULTS, "bound.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
        for r in rows:
            if r["view"] != "xray +z" or not r["ours"].get("pixels"):
                continue
            ax[0].plot([r["keep"] * 100], [r["ours"]["p50"]], "o", color="C0")
            ax[0].plot([r["keep"] * 100], [r["ours"]["p90"]], "v", color="C0")
            if r.get("zfp", {}).get("pixels"):
                ax[0].plot([r["keep"] * 100], [r["zfp"]["p50"]], "s", color="C3")
                ax[0].plot([r["keep"] * 100], [r["zfp"]["p90"]], "^", color="C3")
        ax[0].set_xscale("log")
        ax[0].set_yscale("log")
        ax[0].set_xlabel("kept coefficients (%)")
        ax[0].set_ylabel("bound / actual error per pixel")
        ax[0].set_title("X-ray +z: wvol (blue: median o, p90 v), ZFP tol x length (red)")
        for i, p in enumerate(prog):
            t = [q["elapsed"] for q in p["passes"] if q["bound_max"] > 0]
            ax[1].plot(t, [q["bound_max"] for q in p["passes"] if q["bound_max"] > 0], "-o", color=f"C{i}",
                       label=f"{p['volume']} bound")
            ax[1].plot(t, [max(q["actual_max"], 1e-30) for q in p["passes"] if q["bound_max"] > 0], "--x",
                       color=f"C{i}", label=f"{p['volume']} actual")
        ax[1].set_yscale("log")
        ax[1].set_xlabel("elapsed seconds")
        ax[1].set_ylabel("largest pixel error")
        ax[1].set_title("progressive passes: bound and actual error")
        ax[1].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(RESULTS, "bound.png"), dpi=110)
    except ImportError:
        print("matplotlib missing: no plot")


def main():
    global RESULTS  # --out moves the results
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--small", type=int, default=48)
    ap.add_argument("--small-image", type=int, default=48)
    ap.add_argument("--keep", default="2,10,30")
    ap.add_argument("--noise", type=float, default=20.0)
    ap.add_argument("--growth", type=float, default=4.0)
    ap.add_argument("--psnr", default="40,60")
    ap.add_argument("--only-wvc", action="store_true")
    ap.add_argument("--out", default=RESULTS, help="folder for bound.json, .md and .png (default bench/results)")
    args = ap.parse_args()
    RESULTS = args.out
    if args.only_wvc:
        with open(os.path.join(RESULTS, "bound.json")) as f:
            old = json.load(f)
        write(args, old["bound_vs_actual"], old["progressive"], part3(args))
        return
    rows = part1(args)
    prog = part2(args)
    write(args, rows, prog, part3(args))


if __name__ == "__main__":
    main()
