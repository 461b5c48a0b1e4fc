#!/usr/bin/env python3
"""The volumetric error map of an mtcal error model, in straightforward numpy.

The same computation as ErrorModel::predictGridUm: every error function (B-spline or
constant) and every joint matrix T_p dT_p T_s dT_s is evaluated once per grid value of its
coordinate, then each grid point chains matrix-vector products through the tool branch and
is expressed in the workpiece frame; E = P_ideal - P in um. Vectorised over all points.

Usage: model_map_numpy.py INPUT.json [REPEATS] [SAMPLES]
INPUT: {"machine": ..., "functions": {name: ErrorFunction JSON}, "axes": [[x...], [y...], [z...]]}
Prints one JSON object: seconds (best of the repeats), points, and "sample": E (um) at SAMPLES
evenly spaced grid points (default 7; 0: every point) by their index in the grid, the last
coordinate varying fastest.
"""
import json
import sys
import time

import numpy as np


def bspline(degree, knots, coefficients, x):
    """de Boor evaluation at one x; outside the base interval the end pieces extend (as in mtcal)."""
    t = knots
    n = len(coefficients)
    mu = degree
    while mu < n - 1 and t[mu + 1] <= x:
        mu += 1
    d = [coefficients[j + mu - degree] for j in range(degree + 1)]
    for r in range(1, degree + 1):
        for j in range(degree, r - 1, -1):
            i = j + mu - degree
            denom = t[i + degree - r + 1] - t[i]
            alpha = 0.0 if denom == 0 else (x - t[i]) / denom
            d[j] = (1 - alpha) * d[j - 1] + alpha * d[j]
    return d[degree]


def value(function, x):
    if "coefficients" in function:
        return bspline(function["degree"], function["knots"], function["coefficients"], x)
    return function["constant"]


def rotation(axis, angle):
    axis = np.asarray(axis, float)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def error_transform(v):
    m = np.eye(4)
    rx, ry, rz = v[3] * 1e-6, v[4] * 1e-6, v[5] * 1e-6
    m[:3, :3] = rotation([0, 0, 1], rz) @ rotation([0, 1, 0], ry) @ rotation([1, 0, 0], rx)
    m[:3, 3] = np.asarray(v[:3]) * 1e-3
    return m


COMPONENT = {"dx": 0, "dy": 1, "dz": 2, "rx": 3, "ry": 4, "rz": 5}


def joint_matrix(joint, q, static_error, motion_error):
    tp = np.eye(4)
    tp[:3, 3] = joint.get("offset_mm", [0, 0, 0])
    ts = np.eye(4)
    kind = joint.get("type", "fixed")
    if kind == "prismatic":
        ts[:3, 3] = np.asarray(joint["axis"], float) * q
    elif kind == "revolute":
        ts[:3, :3] = rotation(joint["axis"], np.radians(q))
    return tp @ error_transform(static_error) @ ts @ error_transform(motion_error)


def main():
    model = json.load(open(sys.argv[1]))
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    samples = int(sys.argv[3]) if len(sys.argv) > 3 else 7
    machine, functions = model["machine"], model["functions"]
    coordinates = []
    for j in machine["joints"]:
        if j.get("type", "fixed") != "fixed" and j["coordinate"] not in coordinates:
            coordinates.append(j["coordinate"])
    axes = model["axes"]  # one list of values per coordinate
    best = None
    for _ in range(repeats):
        start = time.perf_counter()
        tables = []  # per joint: (coordinate index or -1, actual (k,4,4), ideal (k,4,4))
        for j in machine["joints"]:
            c = coordinates.index(j["coordinate"]) if j.get("type", "fixed") != "fixed" else -1
            values = axes[c] if c >= 0 else [0.0]
            actual, ideal = [], []
            for q in values:
                se, me = np.zeros(6), np.zeros(6)
                for kind, target in (("static_errors", se), ("motion_errors", me)):
                    for name, comp in j.get(kind, {}).items():
                        if name in functions:
                            target[COMPONENT[comp]] += value(functions[name], q if kind == "motion_errors" else 0.0)
                actual.append(joint_matrix(j, q, se, me))
                ideal.append(joint_matrix(j, q, np.zeros(6), np.zeros(6)))
            tables.append((c, np.array(actual), np.array(ideal)))
        grids = np.meshgrid(*[np.arange(len(v)) for v in axes], indexing="ij")
        index = [g.ravel() for g in grids]
        bodies = [j["body"] for j in machine["joints"]]

        def branch(body):
            chain = []
            while body != machine.get("bed", "bed"):
                k = bodies.index(body)
                chain.insert(0, k)
                body = machine["joints"][k]["parent"]
            return chain

        tool, work = branch(machine["tool"]), branch(machine["workpiece"])
        points = index[0].size
        tool_point = np.append(np.asarray(machine.get("tool_point_mm", [0, 0, 0]), float), 1.0)

        def through(ideal):
            v = np.broadcast_to(tool_point, (points, 4)).copy()
            for k in reversed(tool):
                c, actual_m, ideal_m = tables[k]
                m = (ideal_m if ideal else actual_m)[index[c] if c >= 0 else np.zeros(points, int)]
                v = np.einsum("nij,nj->ni", m, v)
            w = np.broadcast_to(np.eye(4), (points, 4, 4))
            for k in work:
                c, actual_m, ideal_m = tables[k]
                m = (ideal_m if ideal else actual_m)[index[c] if c >= 0 else np.zeros(points, int)]
                w = w @ m
            rt = np.transpose(w[:, :3, :3], (0, 2, 1))
            return np.einsum("nij,nj->ni", rt, v[:, :3] - w[:, :3, 3])

        e = (through(True) - through(False)) * 1000.0
        elapsed = time.perf_counter() - start
        best = elapsed if best is None else min(best, elapsed)
    sample = range(points) if samples == 0 else [int(i) for i in np.linspace(0, points - 1, samples)]
    print(json.dumps({"seconds": best, "points": int(points), "sample": {str(i): e[i].tolist() for i in sample}}))


if __name__ == "__main__":
    main()
