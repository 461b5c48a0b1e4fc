#!/usr/bin/python3
"""Independent numpy implementation of the gantry point accuracy evaluation (patent
CN106017326, docs/gantry.md): the reference for bench/gantry_bench.cpp, written from the
patent and docs/gantry.md, not from mtcal's C++.

  gantry_numpy.py MEASUREMENTS.json [repeats]

Prints one JSON object: {"seconds": best time of the evaluation, "holes": n,
"dp_um": [[dx, dy, dz], ...]}. TCP0 from the A and C axes, the patent's three-point frame
(the first three targets), the passes' outliers left out as the docs say.
"""
import json
import sys
import time

import numpy as np


def fit_plane(p):
    c = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - c, full_matrices=False)
    return c, vt[2]


def fit_line(p):
    c = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - c, full_matrices=False)
    d = vt[0]
    if d @ (p[-1] - p[0]) < 0:
        d = -d
    return c, d


def line_distances(p, c, d):
    r = p - c
    return np.linalg.norm(r - np.outer(r @ d, d), axis=1)


def robust_line(p):
    c, d = fit_line(p)
    dist = line_distances(p, c, d)
    cut = max(5.0 * np.median(dist), 0.005)
    keep = dist <= cut
    if keep.all() or keep.sum() < 2:
        return c, d
    return fit_line(p[keep])


def fit_circle(p):
    c, n = fit_plane(p)
    u = p[0] - c
    u -= (u @ n) * n
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    xy = np.column_stack(((p - c) @ u, (p - c) @ v))
    # Kasa, then Gauss-Newton on the geometric distances.
    m = xy.mean(axis=0)
    q = xy - m
    a = np.column_stack((q, np.ones(len(q))))
    k = np.linalg.lstsq(a, (q ** 2).sum(axis=1), rcond=None)[0]
    x = np.array([k[0] / 2, k[1] / 2, 0.0])
    x[2] = np.sqrt(k[2] + x[0] ** 2 + x[1] ** 2)
    for _ in range(100):
        r = q - x[:2]
        dist = np.linalg.norm(r, axis=1)
        j = np.column_stack((-r[:, 0] / dist, -r[:, 1] / dist, -np.ones(len(dist))))
        step = np.linalg.lstsq(j, -(dist - x[2]), rcond=None)[0]
        x += step
        if np.linalg.norm(step) <= 1e-13 * max(1.0, x[2]):
            break
    centre2 = m + x[:2]
    ang = np.unwrap(np.arctan2(xy[:, 1] - centre2[1], xy[:, 0] - centre2[0]))
    normal = n if ang[-1] - ang[0] >= 0 else -n
    return c + centre2[0] * u + centre2[1] * v, normal


def frame(a, b, c):
    x = (b - a) / np.linalg.norm(b - a)
    z = np.cross(b - a, c - a)
    z /= np.linalg.norm(z)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross(z, x), z, a
    return m


def evaluate(m):
    r = m["reflector_radius_mm"]
    corners = m["corners"]
    tops = np.array([p for c in corners for p in c.get("top", [])])
    passes = [(g["direction"], np.array(g["points"])) for g in m["gantry_passes"]]
    gantry = np.vstack([p for _, p in passes])
    bed = tops.mean(axis=0)
    c_top, z = fit_plane(tops)
    if z @ (gantry.mean(axis=0) - bed) < 0:
        z = -z
    c_top = c_top - r * z
    origin_corner = next(c for c in corners if c["name"] == m["origin_corner"])
    planes = [(z, c_top)]
    for key in ("side_1", "side_2"):
        p = np.array(origin_corner[key])
        c, n = fit_plane(p)
        if n @ (p.mean(axis=0) - bed) < 0:
            n = -n
        planes.append((n, c - r * n))
    a = np.array([n for n, _ in planes])
    origin = np.linalg.solve(a, np.array([n @ c for n, c in planes]))
    d = np.zeros(3)
    for direction, p in passes:
        _, dd = robust_line(p)
        d += dd if direction >= 0 else -dd
    d /= np.linalg.norm(d)
    x = d - (d @ z) * z
    x /= np.linalg.norm(x)
    rot = np.column_stack((x, np.cross(z, x), z)).T  # tracker -> global

    def g(p):
        return (np.asarray(p) - origin) @ rot.T

    cc, cn = fit_circle(g(m["c_sweep"]))
    if cn[2] < 0:
        cn = -cn
    ac, an = fit_circle(g(m["a_sweep"]))
    if an[0] < 0:
        an = -an
    # Common perpendicular: the foot on the C axis is the wrist centre.
    b = cn @ an
    w = cc - ac
    s = (b * (an @ w) - cn @ w) / (1 - b * b)
    wrist = cc + s * cn
    tcp0 = wrist - m["tool_length_mm"] * cn
    init = g(m["initial_targets"])
    m0inv = np.linalg.inv(frame(*init[:3]))
    np0 = np.array(m["initial_np_mm"])
    out = []
    for h in m["holes"]:
        t = g(h["targets"])
        ti = frame(*t[:3]) @ m0inv
        tcp = ti[:3, :3] @ tcp0 + ti[:3, 3]
        npg = tcp0 + (np.array(h["np_mm"]) - np0)
        out.append(((tcp - npg) * 1000.0).tolist())
    return out


def main():
    with open(sys.argv[1]) as f:
        m = json.load(f)
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        dp = evaluate(m)
        best = min(best, time.perf_counter() - t0)
    print(json.dumps({"seconds": best, "holes": len(dp), "dp_um": dp}))


if __name__ == "__main__":
    main()
