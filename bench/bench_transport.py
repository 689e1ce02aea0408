#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Lewis & Fournier 2002, Figs. 4-5: accuracy of the transport coefficients against time for each
2D quadrature rule and several sample counts.

Test problem (as in the paper): all T_jk of one destination level for one source basis j and a
fixed geometry: here the stained-glass scene's window (unit square at z = 1, facing down) and floor
(3 x 3 at z = 0), j = (level 1, m = (0, 0, 1, 1)) (the window's quarter that emits towards the 45°
peak), every k of destination level --level (16^level coefficients). The reference vector is a long
jittered (stratified) integration with --ref-samples points per coefficient; a second, independent
long run (Hammersley, same count) measures the reference's own error, listed as the floor.

  RED = ||T - T_ref||_2 / ||T_ref||_2          RMD = max |T - T_ref| / max |T_ref|

Times: wall seconds of one call that integrates all the coefficients (the fastest of --repeat), on
the machine the run was taken on (2 shared cores: ratios are the reliable part). All rules run in
this one process, interleaved, so they see the same load.

Writes bench/results/transport.json, transport_red.png, transport_rmd.png (and transport.md, the
summary of which of the paper's findings hold). Smoke run: bench/bench_transport.py --quick
"""
import argparse
import json
import math
import os
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, os.environ.get("WVOL_PYTHONPATH", str(ROOT / "build" / "python")))
import wvol  # noqa: E402

T = wvol.transport
WINDOW = [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]]
FLOOR = [[-0.5, -1, 0], [2.5, -1, 0], [2.5, 2, 0], [-0.5, 2, 0]]
J = (1, 0, 0, 1, 1)

GRID = [4, 9, 16, 36, 64, 144, 256, 576, 1024, 4096, 16384]          # trapezoid, stratified: n^2
ROMBERG = [(2 ** m + 1) ** 2 for m in range(1, 8)]                     # (2^m + 1)^2
SEQ = [4, 16, 64, 256, 1024, 4096, 16384]                              # MC, Halton, Hammersley


def counts(rule, quick):
    c = ROMBERG if rule.startswith("romberg") else GRID if rule in ("trapezoid", "stratified") else SEQ
    return [n for n in c if n <= (1100 if quick else 1 << 30)]


def timed(fn, repeat):
    best, out = math.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def metrics(t, ref):
    return (float(np.linalg.norm(t - ref) / np.linalg.norm(ref)),
            float(np.max(np.abs(t - ref)) / np.max(np.abs(ref))))


def interp_at(rows, when):
    """log-log interpolation of RED at a time (None outside the measured range)"""
    ts = [r["seconds"] for r in rows]
    if when < min(ts) or when > max(ts):
        return None
    pts = sorted((r["seconds"], r["red"]) for r in rows)
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if t0 <= when <= t1:
            if t1 == t0:
                return min(e0, e1)
            a = (math.log(when) - math.log(t0)) / (math.log(t1) - math.log(t0))
            return math.exp((1 - a) * math.log(max(e0, 1e-300)) + a * math.log(max(e1, 1e-300)))
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--level", type=int, default=3, help="destination level (16^level coefficients)")
    ap.add_argument("--ref-samples", type=int, default=1024 * 1024)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="smoke run: small counts, short reference")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results"))
    a = ap.parse_args()
    if a.quick:
        a.ref_samples, a.repeat = 128 * 128, 1
    out = pathlib.Path(a.out)
    out.mkdir(parents=True, exist_ok=True)

    t0 = time.perf_counter()
    ref = T.coefficients(WINDOW, FLOOR, J, a.level, "stratified", a.ref_samples, seed=12345)
    ref_seconds = time.perf_counter() - t0
    ref2 = T.coefficients(WINDOW, FLOOR, J, a.level, "hammersley", a.ref_samples)
    floor_red, floor_rmd = metrics(ref2, ref)
    print(f"reference: {a.ref_samples} stratified points x {ref.size} coefficients in {ref_seconds:.1f} s; "
          f"independent Hammersley reference differs by RED {floor_red:.2e}, RMD {floor_rmd:.2e}", flush=True)

    rows = {q: [] for q in T.QUADRATURES}
    # interleave the rules at each size rank so that load changes hit them alike
    plan = [(q, n) for q in T.QUADRATURES for n in counts(q, a.quick)]
    plan.sort(key=lambda qn: (counts(qn[0], a.quick).index(qn[1]), qn[0]))
    for q, n in plan:
        t, sec = timed(lambda: T.coefficients(WINDOW, FLOOR, J, a.level, q, n), a.repeat)
        red, rmd = metrics(t, ref)
        rows[q].append({"samples": n, "seconds": sec, "red": red, "rmd": rmd})
        print(f"{q:12s} N={n:6d}  {sec:8.4f} s  RED {red:.3e}  RMD {rmd:.3e}", flush=True)

    # the paper's findings, measured
    def at_n(q, n):
        return next((r for r in rows[q] if r["samples"] == n), None)

    common = [n for n in SEQ if at_n("monte-carlo", n) and at_n("stratified", n)]
    strat_gain = [at_n("monte-carlo", n)["red"] / at_n("stratified", n)["red"] for n in common]
    qmc_gain = {q: [at_n("monte-carlo", n)["red"] / at_n(q, n)["red"] for n in SEQ if at_n(q, n)]
                for q in ("halton", "hammersley")}
    times = sorted({r["seconds"] for q in rows for r in rows[q]})
    probe = [t for t in np.geomspace(times[0], times[-1], 7)[1:-1]]
    at_time = []
    for t in probe:
        e = {q: interp_at(rows[q], t) for q in rows}
        e = {q: v for q, v in e.items() if v is not None}
        if len(e) >= 3:
            rank = sorted(e, key=e.get)
            at_time.append({"seconds": t, "red": e, "rank": rank})
    trap_rank = [r["rank"].index("trapezoid") + 1 for r in at_time if "trapezoid" in r["red"]]
    romberg_order = {q: float(np.median([r["red"] for r in rows[q]])) for q in ("romberg1", "romberg2", "romberg3")}
    findings = {
        "stratification_improves_monte_carlo": {
            "holds": bool(np.median(strat_gain) > 1), "red_ratio_mc_over_stratified_by_n": dict(zip(common, strat_gain))},
        "quasi_random_beats_pseudo_random": {
            "holds": bool(all(np.median(v) > 1 for v in qmc_gain.values())),
            "red_ratio_mc_over_qmc_by_n": {q: dict(zip([n for n in SEQ if at_n(q, n)], v)) for q, v in qmc_gain.items()}},
        "trapezoid_2d_competitive": {
            "holds": bool(trap_rank and np.median(trap_rank) <= 3),
            "rank_of_trapezoid_at_equal_time (1 = best of 8)": trap_rank},
        "higher_romberg_extrapolation_worse": {
            "holds": bool(romberg_order["romberg3"] >= romberg_order["romberg2"] >= romberg_order["romberg1"]),
            "median_red": romberg_order},
    }
    doc = {
        "problem": {"source": WINDOW, "destination": FLOOR, "j": J, "destination_level": a.level,
                    "coefficients": int(ref.size), "nonzero_reference_coefficients": int(np.count_nonzero(ref))},
        "reference": {"rule": "stratified", "samples": a.ref_samples, "seconds": ref_seconds,
                      "independent_hammersley_red": floor_red, "independent_hammersley_rmd": floor_rmd},
        "machine": os.uname().nodename + " (2 shared cores)", "repeat": a.repeat,
        "rows": rows, "equal_time": at_time, "findings": findings,
    }
    (out / "transport.json").write_text(json.dumps(doc, indent=1))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    styles = {"trapezoid": "k-o", "romberg1": "b-s", "romberg2": "b--s", "romberg3": "b:s", "monte-carlo": "r-^",
              "stratified": "r--v", "halton": "g-D", "hammersley": "g--d"}
    for metric, fig in (("red", "Fig. 4: relative Euclidean distance"), ("rmd", "Fig. 5: relative maximum departure")):
        plt.figure(figsize=(7, 5))
        for q in T.QUADRATURES:
            r = rows[q]
            plt.loglog([x["seconds"] for x in r], [max(x[metric], 1e-12) for x in r], styles[q], label=q, ms=4)
        plt.axhline(floor_red if metric == "red" else floor_rmd, color="grey", lw=0.8, ls=":",
                    label="reference's own error")
        plt.xlabel("seconds for all %d T_jk of level %d" % (ref.size, a.level))
        plt.ylabel(metric.upper())
        plt.title(fig + " vs time")
        plt.legend(fontsize=8)
        plt.grid(True, which="both", lw=0.3)
        plt.tight_layout()
        plt.savefig(out / f"transport_{metric}.png", dpi=110)
        plt.close()
    lines = ["# Transport coefficient quadrature (Lewis & Fournier 2002, Figs. 4-5)", "",
             f"{ref.size} T_jk (destination level {a.level}, {np.count_nonzero(ref)} non-zero) for j = {J}, "
             f"window -> floor; reference: {a.ref_samples} stratified points per coefficient "
             f"({ref_seconds:.0f} s), independent Hammersley reference within RED {floor_red:.1e}.", ""]
    for k, v in findings.items():
        lines.append(f"- {k.replace('_', ' ')}: **{'holds' if v['holds'] else 'does not hold'}**")
    (out / "transport.md").write_text("\n".join(lines) + "\n")
    print(json.dumps(findings, indent=1))


if __name__ == "__main__":
    main()
