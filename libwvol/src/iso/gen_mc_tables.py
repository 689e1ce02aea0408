#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Generates mc_tables.c: the 256-case marching-cubes table of libwvol.

Derived, not copied: for each case the intersection points (one per cube edge
whose corners differ) are joined on every face by segments, with one fixed rule
for ambiguous faces (two positive corners on a diagonal): the positive corners
are separated ("always separate positive"; the negative corners are joined).
Neighbouring cells see the same face and so make the same decision, which is
what makes closed surfaces closed. Each face segment is directed so that, seen
from outside the cube, the positive corners lie on its left; a neighbour sees
the face from the other side and walks the segment the other way, so the loops
of all cells form one consistently oriented surface. Each loop is triangulated
(a fan; the hexagon as a balanced 4-triangle split), and the winding is flipped
once globally so that normals point from f >= iso towards f < iso.

Conventions (shared with mc.c):
  corner n in 0..7: (x, y, z) = (n & 1, (n >> 1) & 1, n >> 2); bit n of the case
  is set when the sample at that corner is >= iso ("positive").
  edge 0..3:  x-edges at (y, z) = (0,0) (1,0) (0,1) (1,1): e = y + 2 z
  edge 4..7:  y-edges at (x, z):                            e = 4 + x + 2 z
  edge 8..11: z-edges at (x, y):                            e = 8 + x + 2 y

Run: python3 gen_mc_tables.py > mc_tables.c
"""
import itertools


def corner(n):
    return (n & 1, (n >> 1) & 1, n >> 2)


def cidx(x, y, z):
    return x | (y << 1) | (z << 2)


EDGES = []  # (corner a, corner b), a is the lower end
for z in (0, 1):
    for y in (0, 1):
        EDGES.append((cidx(0, y, z), cidx(1, y, z)))
for z in (0, 1):
    for x in (0, 1):
        EDGES.append((cidx(x, 0, z), cidx(x, 1, z)))
for y in (0, 1):
    for x in (0, 1):
        EDGES.append((cidx(x, y, 0), cidx(x, y, 1)))
assert EDGES[0] == (0, 1) and EDGES[4] == (0, 2) and EDGES[8] == (0, 4)
assert EDGES[1 + 2 * 1] == (cidx(0, 1, 1), cidx(1, 1, 1))
assert EDGES[4 + 1 + 2 * 1] == (cidx(1, 0, 1), cidx(1, 1, 1))
assert EDGES[8 + 1 + 2 * 1] == (cidx(1, 1, 0), cidx(1, 1, 1))


def edge_of(a, b):
    key = (min(a, b), max(a, b))
    return EDGES.index(key)


def mid(e):
    a, b = EDGES[e]
    pa, pb = corner(a), corner(b)
    return tuple((pa[i] + pb[i]) / 2 for i in range(3))


# faces: (axis, side) -> corners in cyclic order, outward normal
FACES = []
for axis in range(3):
    for side in (0, 1):
        u, v = [a for a in range(3) if a != axis]
        cyc = []
        for (cu, cv) in ((0, 0), (1, 0), (1, 1), (0, 1)):
            p = [0, 0, 0]
            p[axis], p[u], p[v] = side, cu, cv
            cyc.append(cidx(*p))
        nrm = [0, 0, 0]
        nrm[axis] = 1 if side else -1
        FACES.append((cyc, tuple(nrm)))


def sub(a, b):
    return tuple(a[i] - b[i] for i in range(3))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return sum(a[i] * b[i] for i in range(3))


def segments(case):
    """Directed segments (edge a -> edge b) on all faces."""
    pos = lambda c: (case >> c) & 1
    segs = []
    for cyc, nrm in FACES:
        fedges = [edge_of(cyc[i], cyc[(i + 1) % 4]) for i in range(4)]
        cut = [i for i in range(4) if pos(cyc[i]) != pos(cyc[(i + 1) % 4])]
        pairs = []
        if len(cut) == 2:
            pairs.append((fedges[cut[0]], fedges[cut[1]]))
        elif len(cut) == 4:
            # ambiguous: separate each positive corner with a segment joining its
            # two face edges (edge i joins cyc[i] and cyc[i+1])
            for i in range(4):
                if pos(cyc[i]):
                    pairs.append((fedges[(i - 1) % 4], fedges[i]))
            assert len(pairs) == 2
        for ea, eb in pairs:
            a, b = mid(ea), mid(eb)
            # positive end of edge ea lies on the positive side of the segment
            c0, c1 = EDGES[ea]
            p = corner(c0) if pos(c0) else corner(c1)
            m = tuple((a[i] + b[i]) / 2 for i in range(3))
            left = cross(nrm, sub(b, a))
            if dot(left, sub(p, m)) > 0:
                segs.append((ea, eb))
            else:
                segs.append((eb, ea))
    return segs


def loops(case):
    segs = segments(case)
    nxt = {}
    for a, b in segs:
        assert a not in nxt, (case, segs)
        nxt[a] = b
    assert sorted(nxt.keys()) == sorted(nxt.values())
    out, seen = [], set()
    for start in sorted(nxt):
        if start in seen:
            continue
        lp, e = [], start
        while e not in seen:
            seen.add(e)
            lp.append(e)
            e = nxt[e]
        assert e == start
        out.append(lp)
    return out


def faces_of_edge(e):
    a, b = EDGES[e]
    return {fi for fi, (cyc, _) in enumerate(FACES) if a in cyc and b in cyc}


def triangulations(idx):
    """All triangulations of the convex polygon idx (list of loop positions)."""
    if len(idx) < 3:
        yield []
        return
    a, b = idx[0], idx[-1]
    for k in range(1, len(idx) - 1):
        for left in triangulations(idx[:k + 1]):
            for right in triangulations(idx[k:]):
                yield left + right + [(a, idx[k], b)]


def quality(p, q, r):
    """min angle-like measure: 4 sqrt(3) area / sum of squared sides."""
    u, v = sub(q, p), sub(r, p)
    c = cross(u, v)
    area = 0.5 * dot(c, c) ** 0.5
    s = dot(u, u) + dot(v, v) + dot(sub(r, q), sub(r, q))
    return 4 * 3 ** 0.5 * area / s


def triangulate(lp):
    """Triangulates a loop without any diagonal between two points on one cube
    face: a neighbour across an ambiguous face could draw the same diagonal, and
    the edge would then belong to four triangles. Among the allowed
    triangulations, the one with the best worst triangle (on edge midpoints)."""
    n = len(lp)
    best, best_q = None, -1.0
    for tri in triangulations(list(range(n))):
        ok = True
        for t in tri:
            for i, j in ((t[0], t[1]), (t[1], t[2]), (t[0], t[2])):
                i, j = min(i, j), max(i, j)
                if j - i not in (1, n - 1) and faces_of_edge(lp[i]) & faces_of_edge(lp[j]):
                    ok = False
        if not ok:
            continue
        # keep the loop's winding: each triangle listed in increasing loop order
        tri = [tuple(sorted(t)) for t in tri]
        q = min(quality(mid(lp[a]), mid(lp[b]), mid(lp[c])) for a, b, c in tri)
        if q > best_q + 1e-12:
            best, best_q = tri, q
    assert best is not None, lp
    return [tuple(lp[i] for i in t) for t in best]


def orientation_sign(case, lp):
    """+1 if the loop's right-hand normal points from positive to negative."""
    pts = [mid(e) for e in lp]
    nrm = [0.0, 0.0, 0.0]
    for i in range(len(pts)):
        c = cross(pts[i], pts[(i + 1) % len(pts)])
        nrm = [nrm[k] + c[k] for k in range(3)]
    d = [0.0, 0.0, 0.0]
    for e in lp:
        a, b = EDGES[e]
        pa, pb = corner(a), corner(b)
        v = sub(pb, pa) if (case >> a) & 1 else sub(pa, pb)  # positive -> negative
        d = [d[k] + v[k] for k in range(3)]
    s = dot(nrm, d)
    assert abs(s) > 1e-9, (case, lp)
    return 1 if s > 0 else -1


def build():
    tables, signs = [], set()
    for case in range(256):
        tris = []
        for lp in loops(case):
            signs.add(orientation_sign(case, lp))
            tris += triangulate(lp)
        tables.append(tris)
    assert len(signs) == 1, "inconsistent loop orientation"
    flip = signs.pop() < 0
    if flip:
        tables = [[(t[0], t[2], t[1]) for t in tris] for tris in tables]
    return tables


def edge_mask(case):
    m = 0
    for e, (a, b) in enumerate(EDGES):
        if ((case >> a) & 1) != ((case >> b) & 1):
            m |= 1 << e
    return m


def main():
    tables = build()
    maxt = max(len(t) for t in tables)
    print("/* SPDX-License-Identifier: MIT */")
    print("/* Marching-cubes case tables: generated by gen_mc_tables.py (do not edit).")
    print(" * Based on: Lorensen & Cline 1987 (marching cubes); ambiguous faces resolved by")
    print(" * the fixed rule \"separate the positive corners\" (see docs/iso.md). */")
    print('#include "iso/mc_tables.h"')
    print()
    print("const uint8_t wvol__mc_ntri[256] = {")
    for r in range(0, 256, 16):
        print("    " + ", ".join(str(len(tables[c])) for c in range(r, r + 16)) + ",")
    print("};")
    print()
    print("const uint16_t wvol__mc_edges[256] = {")
    for r in range(0, 256, 8):
        print("    " + ", ".join("0x%03x" % edge_mask(c) for c in range(r, r + 8)) + ",")
    print("};")
    print()
    print("const uint8_t wvol__mc_tris[256][%d] = {" % (3 * maxt))
    for c in range(256):
        flat = [e for t in tables[c] for e in t]
        flat += [255] * (3 * maxt - len(flat))
        print("    {" + ", ".join(str(x) for x in flat) + "},")
    print("};")
    import sys
    print("max triangles per case: %d" % maxt, file=sys.stderr)


if __name__ == "__main__":
    main()
