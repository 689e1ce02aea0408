#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Chunk mode 3 (static-model rANS) against mode 2 (CABAC with block flags), chunk by chunk.

Each volume is compressed three times with the same step (so the quantised coefficients are
the same): `--coder cabac` (mode 2 everywhere), `--coder rans` (mode 3 wherever a chunk has no
low-pass cube) and `--coder auto` (the rule in docs/wvc-format.md). The chunk index of the first
two files gives each chunk's bytes in both modes and its non-zero count; from them the bytes
of any per-chunk rule are computed (density thresholds, with and without coding both ways below
a non-zero count), and the auto file's bytes are checked against the rule it implements.

Volumes (256^3 by default): the noisy skull (`--noise 20`) and the turbulence field with db2,
and the clean skull, Shepp-Logan and Gaussian phantoms with haar, db2 and bl3; 40, 50, 60 dB.
Writes bench/results/mode3.json and mode3.md.
    python3 bench/bench_mode3.py [--size 256] [--wvol build/wvol]
"""
import argparse
import json
import os
import struct
import subprocess
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# the rule --coder auto implements (libwvol/src/codec/wvc2_chunk.c)
AUTO_DENSITY, AUTO_ALONE = 0.25, 65536


def chunks(path):
    """[(level, coefficients, nonzero, bytes)] of a version-2 file, from its header and index."""
    b = open(path, "rb").read()
    nsec = struct.unpack_from("<I", b, 12)[0]
    levels = b[32]
    txy, tz = 1 << b[33], 1 << b[34]
    p = struct.unpack_from("<3Q", b, 64)
    nchunks = struct.unpack_from("<Q", b, 208)[0]
    tile = (txy, txy, tz)
    out = []
    for m in range(levels, 0, -1):
        e = [(p[a] >> m) if p[a] > 1 else 1 for a in range(3)]
        nb = sum(1 for band in range(0 if m == levels else 1, 8)
                 if all(not (band >> a & 1) or p[a] > 1 for a in range(3)))
        nt = [(e[a] + tile[a] - 1) // tile[a] for a in range(3)]
        for tzi in range(nt[2]):
            for tyi in range(nt[1]):
                for txi in range(nt[0]):
                    ext = [min(tile[a], e[a] - t * tile[a]) for a, t in enumerate((txi, tyi, tzi))]
                    out.append([m, nb * ext[0] * ext[1] * ext[2]])
    assert len(out) == nchunks, (len(out), nchunks)
    base = 224 + 48 * nsec
    for i in range(nchunks):
        _, nbytes, _, _, nz, _ = struct.unpack_from("<QIIfId", b, base + 32 * i)
        out[i] += [nz, nbytes]
    return [tuple(c) for c in out], levels


def rule_bytes(cab, rans, levels, density, alone):
    """Bytes of the rule: mode 3 where dense (alone from `alone` non-zeros, else the smaller)."""
    total = 0
    for (m, cnt, nz, bc), (_, _, _, br) in zip(cab, rans):
        dense = m != levels and nz > 0 and nz >= density * cnt
        total += (br if nz >= alone else min(br, bc)) if dense else bc
    return total


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--wvol", default=os.path.join(ROOT, "build", "wvol"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "mode3"))
    a = ap.parse_args()
    n = a.size
    cases = [("skull-noisy", "db2"), ("turbulence", "db2")] + [
        (k, w) for k in ("skull", "shepp-logan", "gaussian") for w in ("haar", "db2", "bl3")]
    rules = [(d, s) for d in (0.0, 0.1, 0.25, 0.5) for s in (0, AUTO_ALONE)]
    rows = []
    with tempfile.TemporaryDirectory(dir="/dev/shm" if os.path.isdir("/dev/shm") else None) as tmp:
        made = None
        for kind, wav in cases:
            raw = os.path.join(tmp, "v.raw")
            if made != kind:
                synth = ["skull", "--noise", "20"] if kind == "skull-noisy" else [kind]
                subprocess.check_call([a.wvol, "synth", *synth, "--size", str(n), "-o", raw],
                                      stdout=subprocess.DEVNULL)
                made = kind
            for db in (40, 50, 60):
                files, sizes = {}, {}
                for coder in ("cabac", "rans", "auto"):
                    files[coder] = os.path.join(tmp, coder + ".wvc")
                    subprocess.check_call([a.wvol, "compress", raw, "--dims", f"{n}x{n}x{n}", "--type", "float32",
                                           "--wavelet", wav, "--psnr", str(db), "--coder", coder, "-o",
                                           files[coder]], stdout=subprocess.DEVNULL)
                    sizes[coder] = os.path.getsize(files[coder])
                cab, levels = chunks(files["cabac"])
                rans, _ = chunks(files["rans"])
                payload_c = sum(c[3] for c in cab)
                head = sizes["cabac"] - payload_c
                row = {"kind": kind, "wavelet": wav, "db": db, "bytes": sizes,
                       "rules": {f"{d}/{s}": head + rule_bytes(cab, rans, levels, d, s) for d, s in rules},
                       "auto_rule": head + rule_bytes(cab, rans, levels, AUTO_DENSITY, AUTO_ALONE),
                       "chunks_mode3_auto": sum(1 for c in cab if c[0] != levels and c[2] >= AUTO_DENSITY * c[1]
                                                and c[2] > 0)}
                rows.append(row)
                print(json.dumps(row), flush=True)
    with open(a.out + ".json", "w") as f:
        json.dump({"size": n, "rows": rows}, f, indent=1)
    L = ["# Chunk mode 3 (static-model rANS) against mode 2 (CABAC), chunk by chunk", "",
         f"`bench/bench_mode3.py`, {n}^3, the same quantiser step for the three files of a case. Bytes "
         "relative to `--coder cabac` (mode 2 everywhere). `rans`: mode 3 on every chunk without the "
         "low-pass cube. A rule `d / s`: mode 3 on the chunks with at least a share d of non-zero "
         "coefficients, alone from s non-zeros on, both ways below s keeping the smaller (s = 0: alone "
         "always). `auto`: the file --coder auto wrote (rule 0.25 / 65536, plus zstd where it wins "
         "elsewhere).", "",
         "| volume | wavelet | dB | cabac bytes | rans | " + " | ".join(f"{d} / {s}" for d, s in rules) +
         " | auto |", "|---|---|---|---|---|" + "---|" * len(rules) + "---|"]
    worst = {k: 0.0 for k in [f"{d}/{s}" for d, s in rules] + ["rans", "auto"]}
    for r in rows:
        c = r["bytes"]["cabac"]
        cells = [f"{r['bytes']['rans'] / c:.4f}"] + [f"{r['rules'][f'{d}/{s}'] / c:.4f}" for d, s in rules] + \
                [f"{r['bytes']['auto'] / c:.4f}"]
        for k in worst:
            v = r["bytes"][k] if k in ("rans", "auto") else r["rules"][k]
            worst[k] = max(worst[k], v / c)
        L.append(f"| {r['kind']} | {r['wavelet']} | {r['db']} | {c} | " + " | ".join(cells) + " |")
    L += ["", "Worst ratio over the cases: " + ", ".join(f"{k} {v:.4f}" for k, v in worst.items())]
    with open(a.out + ".md", "w") as f:
        f.write("\n".join(L) + "\n")


if __name__ == "__main__":
    main()
