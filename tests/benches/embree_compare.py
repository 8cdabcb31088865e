#!/usr/bin/env python3
"""Casts the rays of `tools/dump_rays.rs` with Embree (the `embreex`
package: Embree 4, `rtcIntersect1` / `rtcOccluded1` per ray) and compares
rays/s and answers with radbake's ray caster (a SIMD BVH4 collapsed from
an obvhs PLOC build).

    cargo run --release --example dump_rays -- --out rays.bin
    pip install embreex numpy
    python3 tests/benches/embree_compare.py rays.bin

Prints how many hit distances and occlusion answers agree, then Embree's
rays/s on one thread and on all threads (Python threads over chunks of rays:
embreex releases the GIL while it traces) beside radbake's, which dump_rays
measured and stored in the file, and their ratio.
"""

import argparse
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor

try:
    import numpy as np
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh
except ImportError as e:  # pragma: no cover - depends on the machine
    print(f"skipped: {e} (pip install embreex numpy)")
    sys.exit(0)


def load(path):
    data = open(path, "rb").read()
    if data[:8] != b"RBRAYS01":
        sys.exit(f"{path}: not a dump_rays file")
    n_tris, n_closest, n_shadow, threads = (int(v) for v in np.frombuffer(data, "<u4", 4, 8))
    obvhs = np.frombuffer(data, "<f8", 4, 24)
    off = 56

    def take(dtype, count, shape):
        nonlocal off
        a = np.frombuffer(data, dtype, count, off).reshape(shape)
        off += a.nbytes
        return a

    tris = take("<f4", n_tris * 9, (n_tris, 3, 3))
    closest = take("<f4", n_closest * 7, (n_closest, 7))
    shadow = take("<f4", n_shadow * 7, (n_shadow, 7))
    hit_t = take("<f4", n_closest, (n_closest,))
    occluded = take("u1", n_shadow, (n_shadow,))
    rates = {"closest-hit": (obvhs[0], obvhs[1]), "occlusion": (obvhs[2], obvhs[3])}
    return tris, closest, shadow, hit_t, occluded, rates, threads


def best_rate(repeat, n, f):
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t)
    return n / best


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("file")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    a = ap.parse_args()

    tris, closest, shadow, hit_t, occluded, obvhs, obvhs_threads = load(a.file)
    t = time.perf_counter()
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(tris))
    # The BVH is built on the first query (rtcCommitScene): time it apart.
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
    build = time.perf_counter() - t

    def split(rays):
        o = np.ascontiguousarray(rays[:, 0:3])
        d = np.ascontiguousarray(rays[:, 3:6])
        tmax = np.ascontiguousarray(np.minimum(rays[:, 6], 1e37).astype(np.float32))
        return o, d, tmax

    co, cd, ct = split(closest)
    so, sd, st = split(shadow)

    def chunks(n, k):
        step = (n + k - 1) // k
        return [(i, min(i + step, n)) for i in range(0, n, step)]

    def run(o, d, tmax, query, threads):
        if threads == 1:
            return scene.run(o, d, dists=tmax.copy(), query=query)
        parts = chunks(len(o), threads * 8)
        with ThreadPoolExecutor(threads) as pool:
            res = pool.map(
                lambda r: scene.run(o[r[0]:r[1]], d[r[0]:r[1]], dists=tmax[r[0]:r[1]].copy(), query=query),
                parts,
            )
            return np.concatenate(list(res))

    # Answers.
    dist = run(co, cd, ct, "DISTANCE", 1)
    occ = run(so, sd, st, "OCCLUDED", 1) != -1
    e_hit = dist < 1e36
    o_hit = np.isfinite(hit_t)
    both = e_hit & o_hit
    rel = np.abs(dist[both] - hit_t[both]) / np.maximum(hit_t[both], 1e-6)
    print(f"{a.file}: {len(tris)} triangles, Embree BVH built in {build:.3f} s")
    print(
        f"closest hit: both hit {both.sum()}, only radbake {(o_hit & ~e_hit).sum()}, only Embree {(e_hit & ~o_hit).sum()}, "
        f"of {len(hit_t)}; distances agree to 1e-4 (relative) on {(rel < 1e-4).sum()} of {both.sum()} "
        f"(median |Δt|/t {np.median(rel) if len(rel) else 0:.1e}, max {rel.max() if len(rel) else 0:.1e}; "
        f"differing by > 1e-3: {(rel > 1e-3).sum()}; "
        f"max |Δt| {np.abs(dist[both] - hit_t[both]).max() if both.any() else 0:.1e} m)"
    )
    agree = (occ == (occluded == 1)).sum()
    print(f"occlusion: answers agree on {agree} of {len(occ)} rays ({occ.sum()} occluded for Embree, {(occluded == 1).sum()} for radbake)")

    for name, (o, d, tmax, query) in {
        "closest-hit": (co, cd, ct, "DISTANCE"),
        "occlusion": (so, sd, st, "OCCLUDED"),
    }.items():
        one = best_rate(a.repeat, len(o), lambda: run(o, d, tmax, query, 1))
        many = best_rate(a.repeat, len(o), lambda: run(o, d, tmax, query, a.threads))
        ours = obvhs[name]
        print(
            f"{name:<11}  Embree {one / 1e6:6.2f} M rays/s on 1 thread, {many / 1e6:6.2f} on {a.threads};  "
            f"radbake {ours[0] / 1e6:6.2f} on 1, {ours[1] / 1e6:6.2f} on {obvhs_threads};  "
            f"radbake/Embree {ours[0] / one:.2f} (1 thread), {ours[1] / many:.2f} (all)"
        )

if __name__ == "__main__":
    main()
