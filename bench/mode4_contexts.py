#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Static entropy of chunk mode 4's magnitude symbols under other contexts and group sizes.

Where do the bytes of `--coder auto` (chunk mode 4) go against `--coder compact` (mode 2) on the
sparse chunks of a 40 dB file? This script quantises a volume's transform with a given step (as
the encoder does: dead zone, f = 0.38) and, per chunk (a 64 x 64 x 32 tile of every band of a
level), sums the ideal code length of the symbols mode 4 codes under per-chunk static tables:

* the 16-group flags (context as mode 4's: bit length of the group's context sum x the OR of its
  parents' classes) and the magnitude symbols of the non-zero groups (mode 4's 52 contexts);
* the same with the left neighbour W added to the context sum (2|W|, weighted as N and U);
* groups of 8 and 4 along x instead of 16;
* mode 2's contexts inside the same groups: the significance by the six parent classes x the
  non-zero face neighbours (W, N, U) x the non-zero diagonal ones, the magnitude of a non-zero
  by mode 2's magnitude class;
* mode 2's sets instead of rows and 16-groups (`--sets`): a flag per 4^3 block (context: its
  parents' largest class x its non-zero causal neighbour blocks), a flag per 2^3 group of a
  non-zero block (mode 2's six parent classes x non-zero neighbour groups; the last group of a
  block implied), then per coefficient of a non-zero group (the last one implied non-zero when
  the others are zero) either mode 2's binarisation (significance by mode 2's context, then the
  magnitude symbol by mode 2's class) or one magnitude symbol by mode 4's context sum, with or
  without W. With `--sets` each total is also given with a rough packed-table cost (4 bits a
  context and 5 a symbol up to its last used one) and as the code length of an adaptive
  multi-symbol model (counts from 1, +24 an event, halved past 2^13; fresh per chunk), what a
  static per-chunk table would be traded for.

Tables and states are not counted (each variant has as many contexts as mode 4, except the
mode-2 one): the difference between variants is what the contexts alone would save. Levels 1
and 2 (the sparse ones at 40 dB). Results: bench/results/mode4_sparse.md.

  python3 bench/mode4_contexts.py VOLUME.raw N STEP [--wavelet db2] [--levels 5] [--sets]

(VOLUME.raw: float32, N^3; STEP: the `step` of `wvol compress --json` for the same volume,
filter and levels.)"""
import argparse
import math
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "build" / "python"))
import wvol  # noqa: E402

TILE, TILE_Z, GROUP = 64, 32, 16


def bitlen(a):
    out = np.zeros(np.shape(a), np.int64)
    x = np.array(a, np.int64)
    while (x > 0).any():
        out += x > 0
        x >>= 1
    return out


def symbol(a):
    """Mode 4's magnitude symbol: 0, 1, or 2n + b (n the bit length, b the bit below the top)."""
    n = bitlen(a)
    b = (a >> np.maximum(n - 2, 0)) & 1
    return np.where(a >= 2, 2 * n + b, a)


def parent_class(p):
    return np.select([p == 0, p == 1, p <= 3], [0, 1, 2], 3)


def bits(ctx, sym):
    """Ideal code length (bits) of sym under one static table per context."""
    key = ctx.astype(np.int64) * 64 + sym
    u, cnt = np.unique(key, return_counts=True)
    tot = np.zeros(u.max() // 64 + 1)
    np.add.at(tot, u // 64, cnt)
    return float(-(cnt * np.log2(cnt / tot[u // 64])).sum())


def table_bits(ctx, sym):
    """A rough packed-table cost: 4 bits a used context, 5 a symbol up to its last used one."""
    key = ctx.astype(np.int64) * 64 + sym
    u = np.unique(key)
    out = 0.0
    for c in np.unique(u // 64):
        syms = u[u // 64 == c] % 64
        out += 4 + (5 * (int(syms.max()) + 1) if len(syms) > 1 else 0)
    return out


def adaptive_bits(ctx, sym, inc=24, limit=1 << 13, nsym=64):
    """Code length of sym, in order, under one adaptive frequency table per context (counts from
    1, +inc an event, halved when their total passes limit)."""
    tab, total = {}, 0.0
    for c, v in zip(ctx.tolist(), sym.tolist()):
        t = tab.get(c)
        if t is None:
            t = tab[c] = [1] * nsym + [nsym]
        total -= math.log2(t[v] / t[nsym])
        t[v] += inc
        t[nsym] += inc
        if t[nsym] > limit:
            for i in range(nsym):
                t[i] = (t[i] + 1) >> 1
            t[nsym] = sum(t[:nsym])
    return total


def causal(f, axis):
    """f moved one step along axis (the causal neighbour's value), 0 outside."""
    g = np.zeros_like(f)
    to, fro = [slice(None)] * 3, [slice(None)] * 3
    to[axis], fro[axis] = slice(1, None), slice(None, -1)
    g[tuple(to)] = f[tuple(fro)]
    return g


def up(f, k):
    """f repeated k times along every axis."""
    return np.repeat(np.repeat(np.repeat(f, k, 0), k, 1), k, 2)


def set_terms(a, pv, pn, pc6, face, dn, mclass, A, W):
    """Mode 2's sets (4^3 blocks, 2^3 groups) over one band's tile a (z, y, x; even extents):
    {variant: [(context, symbol), ...]}."""
    az, ay, ax = a.shape
    nz = a != 0
    blk = nz.reshape(az // 4, 4, ay // 4, 4, ax // 4, 4).any(axis=(1, 3, 5))
    bcls = np.minimum(pv.reshape(az // 4, 4, ay // 4, 4, ax // 4, 4).max(axis=(1, 3, 5)), 2)
    bnb = causal(blk, 2).astype(int) + causal(blk, 1) + causal(blk, 0)
    flags = [((bcls * 4 + bnb).ravel(), blk.ravel().astype(np.int64))]
    grp = nz.reshape(az // 2, 2, ay // 2, 2, ax // 2, 2).any(axis=(1, 3, 5))
    gnb = causal(grp, 2).astype(int) + causal(grp, 1) + causal(grp, 0)
    last_g = ((np.arange(az // 2)[:, None, None] % 2) * 4 + (np.arange(ay // 2)[None, :, None] % 2) * 2 +
              (np.arange(ax // 2)[None, None, :] % 2)) == 7
    alone_g = up(grp.reshape(az // 4, 2, ay // 4, 2, ax // 4, 2).sum(axis=(1, 3, 5)), 2) == 1
    coded_g = up(blk, 2) & ~(last_g & alone_g & grp)
    flags.append(((pc6[::2, ::2, ::2] * 4 + gnb)[coded_g], grp[coded_g].astype(np.int64)))
    last_c = ((np.arange(az)[:, None, None] % 2) * 4 + (np.arange(ay)[None, :, None] % 2) * 2 +
              (np.arange(ax)[None, None, :] % 2)) == 7
    implied = last_c & (up(nz.reshape(az // 2, 2, ay // 2, 2, ax // 2, 2).sum(axis=(1, 3, 5)), 2) == 1) & nz
    coded = up(grp, 2) & ~implied
    sym = symbol(a)
    imp = (mclass[implied] + 100, sym[implied])
    sig = pc6 * 16 + face * 4 + dn
    out = {"sets, mode 2's binarisation": flags + [(sig[coded], nz[coded].astype(np.int64)), (mclass[nz], sym[nz])]}
    for name, s in (("", A), ("+W", A + 2 * W)):
        ctx = np.minimum(bitlen(np.minimum(s, 65535)), 12) * 5 + pc6
        out[f"sets, one symbol by mode 4's sum{name}"] = flags + [(ctx[coded], sym[coded]), imp]
    return out


def band(q, n, m, b):
    e = n >> m
    o = [e if b & (1 << a) else 0 for a in range(3)]  # x, y, z
    return q[o[2]:o[2] + e, o[1]:o[1] + e, o[0]:o[0] + e]


def chunk_terms(a, pv, pn, sets=False):
    """The per-variant (context, symbol) arrays of one band's tile a (z, y, x), its parents' |q|
    pv and their non-zero neighbour counts pn (both per coefficient)."""
    p = np.pad(a, ((1, 0), (1, 1), (1, 1)))  # one slice before, one row and column either side
    az, ay, ax = a.shape
    N, Nm, Np = p[1:, :ay, 1:ax + 1], p[1:, :ay, :ax], p[1:, :ay, 2:ax + 2]
    U, Um, Up = p[:az, 1:ay + 1, 1:ax + 1], p[:az, 1:ay + 1, :ax], p[:az, 1:ay + 1, 2:ax + 2]
    Uym, Uyp, W = p[:az, :ay, 1:ax + 1], p[:az, 2:ay + 2, 1:ax + 1], p[1:, 1:ay + 1, :ax]
    diag = (Nm, Np, Um, Up, Uym, Uyp)
    A = np.minimum(2 * (N + U) + sum(diag), 65535)
    pc = parent_class(pv)
    rows = a.any(axis=2)
    out = {}
    for g in (16, 8, 4):
        ng = ax // g
        nzg = a.reshape(az, ay, ng, g).any(axis=3)
        coded = np.repeat(nzg, g, axis=2)
        flag_rows = np.repeat(rows[:, :, None], ng, axis=2)
        fctx = np.minimum(bitlen(A.reshape(az, ay, ng, g).sum(axis=3)), 7) * 4 + \
            np.minimum(pc.reshape(az, ay, ng, g).max(axis=3), 3)
        for name, s in (("", A), ("+W", A + 2 * W)):
            ctx = np.minimum(bitlen(np.minimum(s, 65535)), 12) * 4 + pc
            out[f"groups of {g}{name}"] = [(fctx[flag_rows], nzg[flag_rows].astype(np.int64)),
                                          (ctx[coded], symbol(a)[coded])]
    coded = np.repeat(a.reshape(az, ay, ax // GROUP, GROUP).any(axis=3), GROUP, axis=2)
    pc6 = np.select([pv >= 2, pv == 1, pn == 0, pn <= 2], [4, 3, 0, 1], 2)
    face = (W != 0).astype(int) + (N != 0) + (U != 0)
    dn = np.minimum(sum((v != 0).astype(int) for v in diag), 3)
    nz = coded & (a != 0)
    mclass = np.minimum(bitlen(2 * (W + N + U) + sum(diag) + 4 * pv), 15)
    out["groups of 16, mode 2's contexts"] = [out["groups of 16"][0],
                                              ((pc6 * 16 + face * 4 + dn)[coded], (a != 0)[coded].astype(np.int64)),
                                              (mclass[nz], symbol(a)[nz])]
    if sets:
        out.update(set_terms(a, pv, pn, pc6, face, dn, np.minimum(bitlen(2 * (W + N + U) + sum(diag) + 4 * pv), 15),
                             A, W))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("volume")
    ap.add_argument("n", type=int)
    ap.add_argument("step", type=float)
    ap.add_argument("--wavelet", default="db2")
    ap.add_argument("--levels", type=int, default=5)
    ap.add_argument("--sets", action="store_true", help="also mode 2's sets, with table costs and adaptive models")
    args = ap.parse_args()
    n = args.n
    v = np.fromfile(args.volume, dtype=np.float32).reshape(n, n, n)
    c = wvol.dwt3(v, args.wavelet, args.levels).data.astype(np.float64)
    q = np.abs(np.sign(c) * np.floor(np.abs(c) / args.step + 0.38)).astype(np.int64)
    print(f"non-zero quantised coefficients: {np.count_nonzero(q)}")
    for m in (1, 2):
        e = n >> m
        t, tz = min(TILE, e), min(TILE_Z, e)
        total = {}
        for z0 in range(0, e, tz):
            for y0 in range(0, e, t):
                for x0 in range(0, e, t):
                    terms = {}
                    for b in range(1, 8):
                        a = band(q, n, m, b)[z0:z0 + tz, y0:y0 + t, x0:x0 + t]
                        par = band(q, n, m + 1, b)
                        pe = par.shape[0]
                        pp = np.pad(par, 1)
                        nbrs = sum((pp[1 + dz:1 + dz + pe, 1 + dy:1 + dy + pe, 1 + dx:1 + dx + pe] != 0).astype(int)
                                   for dz, dy, dx in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)))
                        Z, Y, X = np.meshgrid(np.arange(z0, z0 + tz) // 2, np.arange(y0, y0 + t) // 2,
                                              np.arange(x0, x0 + t) // 2, indexing="ij")
                        for k, parts in chunk_terms(a, par[Z, Y, X], nbrs[Z, Y, X], args.sets).items():
                            acc = terms.setdefault(k, [([], []) for _ in parts])
                            for (cs, ss), (cx, sx) in zip(acc, parts):
                                cs.append(cx)
                                ss.append(sx)
                    for k, acc in terms.items():
                        parts = [(np.concatenate(cs), np.concatenate(ss)) for cs, ss in acc]
                        tk = total.setdefault(k, [0.0, 0.0, 0.0])
                        tk[0] += sum(bits(c, v) for c, v in parts)
                        if args.sets:
                            tk[1] += sum(table_bits(c, v) for c, v in parts)
                            tk[2] += sum(adaptive_bits(c, v) for c, v in parts)
        for k, (b, tb, ad) in total.items():
            more = f"; + tables ~{tb / 8:7.0f}; adaptive {ad / 8:10.0f}" if args.sets else ""
            print(f"level {m}: {k:42s} {b / 8:10.0f} bytes (flags and magnitude symbols, no tables){more}")


if __name__ == "__main__":
    main()
